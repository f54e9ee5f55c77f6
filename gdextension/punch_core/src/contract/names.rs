//! Matching names at compile time: the contract's tables (which features the policy observes, how the mirror
//! moves each entry) are resolved by name in `const` items, so a name without a rule stops the build.

/// Whether `name` is `parts` joined end to end.
pub const fn is_joined(name: &str, parts: &[&str]) -> bool {
    let name = name.as_bytes();
    let mut at = 0;
    let mut part = 0;
    while part < parts.len() {
        let bytes = parts[part].as_bytes();
        if at + bytes.len() > name.len() {
            return false;
        }
        let mut i = 0;
        while i < bytes.len() {
            if name[at + i] != bytes[i] {
                return false;
            }
            i += 1;
        }
        at += bytes.len();
        part += 1;
    }
    at == name.len()
}

/// Whether two names are the same.
pub const fn same(a: &str, b: &str) -> bool {
    is_joined(a, &[b])
}

/// Whether `name` begins with `prefix`.
pub const fn starts_with(name: &str, prefix: &str) -> bool {
    let (name, prefix) = (name.as_bytes(), prefix.as_bytes());
    if prefix.len() > name.len() {
        return false;
    }
    let mut i = 0;
    while i < prefix.len() {
        if name[i] != prefix[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Whether `name` ends with `suffix`.
pub const fn ends_with(name: &str, suffix: &str) -> bool {
    let (name, suffix) = (name.as_bytes(), suffix.as_bytes());
    if suffix.len() > name.len() {
        return false;
    }
    let offset = name.len() - suffix.len();
    let mut i = 0;
    while i < suffix.len() {
        if name[offset + i] != suffix[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Index of the name that is `parts` joined, if any.
pub const fn index_of_joined(names: &[&str], parts: &[&str]) -> Option<usize> {
    let mut i = 0;
    while i < names.len() {
        if is_joined(names[i], parts) {
            return Some(i);
        }
        i += 1;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_match_as_str_does() {
        assert!(is_joined("fist_r_pos_x", &["fist_r_pos", "_", "x"]));
        assert!(!is_joined("fist_r_pos_x", &["fist_r_pos", "_"]));
        assert!(!is_joined("fist_r_pos", &["fist_r_pos", "_", "x"]));
        assert!(is_joined("", &[]));
        assert!(same("a", "a") && !same("a", "ab") && !same("ab", "a"));
        for (name, affix) in [("bag_pos_x", "bag"), ("bag_pos_x", "_x"), ("a", "abc"), ("", ""), ("abc", "abc")] {
            assert_eq!(starts_with(name, affix), name.starts_with(affix), "{name} {affix}");
            assert_eq!(ends_with(name, affix), name.ends_with(affix), "{name} {affix}");
        }
        assert_eq!(index_of_joined(&["a_x", "b_x", "b_y"], &["b", "_", "y"]), Some(2));
        assert_eq!(index_of_joined(&["a_x"], &["b"]), None);
    }
}
