//! Finding the punching body's bones in a user's skeleton, from bone names and the hierarchy alone (what
//! `Skeleton3D` gives: `get_bone_name(i)` and `get_bone_parent(i)`, -1 for a root).
//!
//! Roles (the simulated body's, `character::Body`): the hips (the pelvis body), the spine chain up to the chest
//! (the torso body; the waist joint sits between hips and chest), the neck and head (kept from the animation,
//! but they give the chest frame its top), and per side an optional shoulder (clavicle), the upper arm, the
//! forearm and the hand (the forearm body ends in the fist).
//!
//! How bones are found:
//! - A name is read as words: a namespace (`mixamorig:`, `mixamorig1:`, anything before the last `:` or `|`) is
//!   dropped, then the name splits at separators (`_ . - :` and spaces), at camelCase and at digits; case does
//!   not matter. A prefix every bone shares (`Character1_`, `Bip01 `, `J_Bip_`) and filler words (`DEF`, `jnt`,
//!   `mixamorig`, `C`, `M`) are dropped; unknown leading words (`CC_Base_`) are dropped at a lower rank.
//! - The side comes from a word: `L`, `Left`, `lft` or `R`, `Right`, `rgt` (`.L`, `_l`, `l_`, `LeftArm`,
//!   `J_Bip_L_Hand`). A name with both or neither is unsided.
//! - What remains must equal one of the role's names (`upperarm`, `arm`, `forearm`, `lowerarm`, `hand`, ...),
//!   so `upperarm_twist_01_r`, `ForeArmRoll`, `LeftHandIndex1` or `ik_hand_r` never match; twist, roll, IK,
//!   control, end and finger bones are also refused outright.
//! - Per side, the arm is the chain upper arm > forearm > hand in which each is a descendant of the one before,
//!   with the best names, then the bones nearest the root (so `upperarm01.R` before `upperarm02.R`). Two namings
//!   are tried: segments (`UpperArm`/`Arm`, `ForeArm`/`LowerArm`, `Hand`/`wrist`) and, when they find no arm,
//!   joints (`Shoulder`, `Elbow`, `Wrist`, as in SMPL or AdvancedSkeleton), so `Shoulder` is the clavicle when an
//!   upper arm follows it and the upper arm when an elbow does.
//! - The chest is the bone both arms branch from (the nearest common ancestor of the two upper arms); the
//!   shoulder is a clavicle- (or shoulder-) named bone strictly between chest and upper arm; the hips are the
//!   nearest ancestor of the chest named `Hips`, `Hip` or `Pelvis`, else the nearest one not named like a spine
//!   bone (MakeHuman's `root`); the spine chain is every bone from just above the hips to the chest; the head is
//!   the `Head` nearest the root outside the arms (else, as in Rigify's `spine.006`, the top of the unsided spine
//!   and neck bones above the chest), and the neck the `Neck` nearest the root between chest and head (else the
//!   first bone between them).
//!
//! Bones chosen by hand (`map_bones_with`, the inspector's edits) hold their roles whatever their names; the
//! other roles are found around them, and a chosen bone that does not fit the hierarchy is refused by name.
//! `BoneMap::unmapped` lists the optional roles left empty (for the node's configuration warnings); a missing
//! required role is a `BoneMapError::Missing` naming each role, what was looked for and below which bone.
//!
//! How the spine shares the waist: the waist joint's rotation (flexion about X, rotation about Y, one rotation
//! vector `v` of the torso relative to the pelvis) is split evenly along the chain: each of its `n` bones turns
//! by `v / n` about the same axis expressed in its own rest frame. Rotations about one axis commute, so the
//! chest ends up turned by exactly `v` relative to the hips, and the back bends over its whole length instead of
//! kinking at one bone. `BoneMap::waist_share` gives the fraction.

use std::collections::HashSet;
use std::fmt;

use crate::contract::character::Body;

/// Which side of the body a bone is on (the character's own left and right).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Side {
    Left,
    Right,
}

impl Side {
    pub const BOTH: [Side; 2] = [Side::Left, Side::Right];

    const fn word(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }

    const fn marks(self) -> &'static str {
        match self {
            Side::Left => "Left, L, .L, _l, l_",
            Side::Right => "Right, R, .R, _r, r_",
        }
    }
}

/// A bone the punching body needs (or may use).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    Hips,
    /// The top of the spine chain, where the arms branch.
    Chest,
    Neck,
    Head,
    /// The clavicle.
    Shoulder(Side),
    UpperArm(Side),
    Forearm(Side),
    Hand(Side),
}

impl Role {
    /// Every role, in the order the inspector would list them.
    pub const ALL: [Role; 12] = [
        Role::Hips,
        Role::Chest,
        Role::Neck,
        Role::Head,
        Role::Shoulder(Side::Left),
        Role::UpperArm(Side::Left),
        Role::Forearm(Side::Left),
        Role::Hand(Side::Left),
        Role::Shoulder(Side::Right),
        Role::UpperArm(Side::Right),
        Role::Forearm(Side::Right),
        Role::Hand(Side::Right),
    ];

    /// Whether a skeleton without this bone is refused (the neck and the shoulders are optional).
    pub const fn is_required(self) -> bool {
        !matches!(self, Role::Neck | Role::Shoulder(_))
    }

    /// A stable snake_case key (`upper_arm_l`), for property names and logs.
    pub const fn key(self) -> &'static str {
        match self {
            Role::Hips => "hips",
            Role::Chest => "chest",
            Role::Neck => "neck",
            Role::Head => "head",
            Role::Shoulder(Side::Left) => "shoulder_l",
            Role::UpperArm(Side::Left) => "upper_arm_l",
            Role::Forearm(Side::Left) => "forearm_l",
            Role::Hand(Side::Left) => "hand_l",
            Role::Shoulder(Side::Right) => "shoulder_r",
            Role::UpperArm(Side::Right) => "upper_arm_r",
            Role::Forearm(Side::Right) => "forearm_r",
            Role::Hand(Side::Right) => "hand_r",
        }
    }

    /// What the matcher looks for, in words for a user.
    pub fn looked_for(self) -> String {
        let sided = |what: &str, side: Side| format!("{what}, marked {} ({})", side.word(), side.marks());
        match self {
            Role::Hips => "an ancestor of the chest named Hips, Hip or Pelvis (else the nearest one not named like \
                           a spine bone)"
                .to_string(),
            Role::Chest => "the spine bone both upper arms branch from".to_string(),
            Role::Neck => "a bone named Neck between the chest and the head".to_string(),
            Role::Head => "an unsided bone named Head above the hips, outside the arms (else the top of the \
                           unsided spine and neck bones above the chest)"
                .to_string(),
            Role::Shoulder(side) => sided(
                "a bone named Clavicle, Collar, Scapula or Shoulder between the chest and \
                                           the upper arm",
                side,
            ),
            Role::UpperArm(side) => sided(
                "a bone named UpperArm, Arm, upper_arm or humerus (or Shoulder, when an \
                                           Elbow follows it)",
                side,
            ),
            Role::Forearm(side) => {
                sided("a bone named ForeArm, LowerArm or lower_arm (or Elbow) below the upper arm", side)
            }
            Role::Hand(side) => sided("a bone named Hand or Wrist below the forearm", side),
        }
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Role::Hips => f.write_str("hips"),
            Role::Chest => f.write_str("chest"),
            Role::Neck => f.write_str("neck"),
            Role::Head => f.write_str("head"),
            Role::Shoulder(side) => write!(f, "{} shoulder", side.word()),
            Role::UpperArm(side) => write!(f, "{} upper arm", side.word()),
            Role::Forearm(side) => write!(f, "{} forearm", side.word()),
            Role::Hand(side) => write!(f, "{} hand", side.word()),
        }
    }
}

/// One arm's bones (indices into the skeleton's bone list).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ArmBones {
    pub shoulder: Option<usize>,
    pub upper_arm: usize,
    pub forearm: usize,
    pub hand: usize,
}

/// Where each role sits in a skeleton (indices into its bone list).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BoneMap {
    pub hips: usize,
    /// From the bone just above the hips up to the chest (the last), each the parent of the next; never empty.
    pub spine: Vec<usize>,
    pub neck: Option<usize>,
    pub head: usize,
    pub left: ArmBones,
    pub right: ArmBones,
}

impl BoneMap {
    /// The chest: the top of the spine chain, where the arms branch.
    pub fn chest(&self) -> usize {
        self.spine[self.spine.len() - 1]
    }

    pub fn arm(&self, side: Side) -> &ArmBones {
        match side {
            Side::Left => &self.left,
            Side::Right => &self.right,
        }
    }

    /// The bone in `role`, if the skeleton has one.
    pub fn bone(&self, role: Role) -> Option<usize> {
        match role {
            Role::Hips => Some(self.hips),
            Role::Chest => Some(self.chest()),
            Role::Neck => self.neck,
            Role::Head => Some(self.head),
            Role::Shoulder(side) => self.arm(side).shoulder,
            Role::UpperArm(side) => Some(self.arm(side).upper_arm),
            Role::Forearm(side) => Some(self.arm(side).forearm),
            Role::Hand(side) => Some(self.arm(side).hand),
        }
    }

    /// The simulated body that `bone` moves with: its role's (the spine's bones the chest's, the clavicles the
    /// chest's, the hands the forearms', the neck the head's), else its nearest ancestor's with one (a finger its
    /// hand's); the hips, the legs and any bone outside the upper body move with the pelvis (the game's root). A
    /// knocked-down rig handed to a ragdoll starts each physical bone with its body's velocity.
    pub fn body_of(&self, bone: usize, parents: &[i32]) -> Body {
        let mut current = Some(bone);
        while let Some(b) = current {
            if self.spine.contains(&b) {
                return Body::Torso;
            }
            if let Some(role) = Role::ALL.into_iter().find(|&role| self.bone(role) == Some(b)) {
                return match role {
                    Role::Hips => Body::Pelvis,
                    Role::Chest | Role::Shoulder(_) => Body::Torso,
                    Role::Neck | Role::Head => Body::Head,
                    Role::UpperArm(Side::Right) => Body::UpperArmR,
                    Role::UpperArm(Side::Left) => Body::UpperArmL,
                    Role::Forearm(Side::Right) | Role::Hand(Side::Right) => Body::ForearmR,
                    Role::Forearm(Side::Left) | Role::Hand(Side::Left) => Body::ForearmL,
                };
            }
            current = parents.get(b).and_then(|&parent| usize::try_from(parent).ok());
        }
        Body::Pelvis
    }

    /// The bone that shows the simulated `body` (the hips the pelvis, the chest the torso, the head, each upper arm
    /// and forearm its own): the rig's bone a hit on that body strikes.
    pub fn bone_showing(&self, body: Body) -> Option<usize> {
        self.bone(match body {
            Body::Pelvis => Role::Hips,
            Body::Torso => Role::Chest,
            Body::Head => Role::Head,
            Body::UpperArmR => Role::UpperArm(Side::Right),
            Body::ForearmR => Role::Forearm(Side::Right),
            Body::UpperArmL => Role::UpperArm(Side::Left),
            Body::ForearmL => Role::Forearm(Side::Left),
        })
    }

    /// The optional roles no bone was found for (for the node's configuration warnings).
    pub fn unmapped(&self) -> Vec<Role> {
        Role::ALL.into_iter().filter(|&role| self.bone(role).is_none()).collect()
    }

    /// The fraction of the waist joint's rotation vector each spine bone turns by (see the module doc).
    pub fn waist_share(&self) -> f32 {
        1.0 / self.spine.len() as f32
    }
}

/// A required role the matcher found no bone for, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MissingRole {
    pub role: Role,
    /// What was searched for and where.
    pub detail: String,
}

impl fmt::Display for MissingRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (looked for {})", self.role, self.detail)
    }
}

/// Why a skeleton cannot drive the punching body.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BoneMapError {
    /// The names and parents do not describe a tree.
    #[error("the skeleton's bone list is malformed: {0}")]
    Malformed(String),
    /// Bones the punching body needs are not in the skeleton (twist, roll, IK and finger bones never count).
    #[error("the skeleton lacks bones the punching body needs: {} (twist, roll, IK and finger bones never count)", list(.0))]
    Missing(Vec<MissingRole>),
    /// A bone chosen by hand for a role is not in the skeleton.
    #[error("the bone `{name}` chosen as the {role} is not in the skeleton")]
    UnknownBone { role: Role, name: String },
    /// A bone chosen by hand does not fit where its role sits (a chest not above the arms, hips not below it).
    #[error("the bone `{name}` chosen as the {role} does not fit: {reason}")]
    Misplaced { role: Role, name: String, reason: String },
}

fn list(missing: &[MissingRole]) -> String {
    missing.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
}

impl BoneMapError {
    /// The roles that were missing (empty for a malformed skeleton).
    pub fn missing_roles(&self) -> Vec<Role> {
        match self {
            BoneMapError::Malformed(_) => Vec::new(),
            BoneMapError::UnknownBone { role, .. } | BoneMapError::Misplaced { role, .. } => vec![*role],
            BoneMapError::Missing(missing) => missing.iter().map(|m| m.role).collect(),
        }
    }
}

/// Finds the punching body's bones in a skeleton given as bone names and parent indices (-1 for a root), in
/// `Skeleton3D`'s order.
pub fn map_bones<S: AsRef<str>>(names: &[S], parents: &[i32]) -> Result<BoneMap, BoneMapError> {
    map_bones_with(names, parents, &[])
}

/// `map_bones` with some roles' bones chosen by hand (by exact bone name, as the inspector edits them): a chosen
/// bone holds its role whatever its name, and the other roles are found around it (a chosen upper arm decides
/// which forearm is below it). A chosen bone that does not fit the hierarchy is an error naming it.
pub fn map_bones_with<S: AsRef<str>>(
    names: &[S],
    parents: &[i32],
    chosen: &[(Role, &str)],
) -> Result<BoneMap, BoneMapError> {
    let tree = Tree::new(parents)?;
    if names.len() != tree.len() {
        return Err(BoneMapError::Malformed(format!("{} names but {} parents", names.len(), tree.len())));
    }
    let mut picked = Vec::with_capacity(chosen.len());
    for &(role, name) in chosen {
        let bone = names
            .iter()
            .position(|n| n.as_ref() == name)
            .ok_or_else(|| BoneMapError::UnknownBone { role, name: name.to_string() })?;
        picked.push((role, bone));
    }
    let words = read_names(names);
    Matcher { tree, words, names: names.iter().map(|n| n.as_ref().to_string()).collect(), chosen: picked }.map()
}

// ---------------------------------------------------------------------------------------------------------
// Names

/// Words that say nothing about the role: rig prefixes and centre marks.
const FILLER: &[&str] =
    &["mixamorig", "bip", "def", "deform", "j", "jnt", "bn", "b", "bone", "c", "m", "center", "centre", "skel", "sk"];
const LEFT: &[&str] = &["l", "left", "lft", "lt"];
const RIGHT: &[&str] = &["r", "right", "rgt", "rt"];
/// A bone with one of these words is never chosen: finger, twist, roll, IK, control and end bones.
const REFUSED_WORDS: &[&str] = &[
    "ik",
    "fk",
    "ctrl",
    "control",
    "target",
    "pole",
    "end",
    "nub",
    "tip",
    "tw",
    "mch",
    "org",
    "helper",
    "corrective",
    "socket",
    "attach",
    "prop",
    "ring",
    "middle",
    "little",
    "carpal",
    "digit",
    "knuckle",
    "phalanx",
];
/// Parts that refuse a bone wherever they appear inside a word (`ForeTwist`, `upperarmtwist`).
const REFUSED_PARTS: &[&str] = &["twist", "roll", "thumb", "index", "pinky", "pinkie", "finger", "metacarpal"];

/// One bone name read as words.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Name {
    side: Option<Side>,
    refused: bool,
    /// The role words joined (`upperarm`) at penalty 0, then with unknown leading words dropped at penalty 1.
    cores: Vec<(String, u32)>,
}

/// Splits a name into lower-case words at separators, camelCase and digit boundaries; digits are dropped.
fn words(name: &str) -> Vec<String> {
    let name = name.rsplit([':', '|']).next().unwrap_or(name);
    let chars: Vec<char> = name.chars().collect();
    let mut words = Vec::new();
    let mut word = String::new();
    for (i, &c) in chars.iter().enumerate() {
        if !c.is_alphanumeric() {
            flush(&mut word, &mut words);
            continue;
        }
        if let Some(&prev) = i.checked_sub(1).and_then(|p| chars.get(p)) {
            let next_lower = chars.get(i + 1).is_some_and(|n| n.is_lowercase());
            let boundary = (c.is_uppercase() && (prev.is_lowercase() || prev.is_ascii_digit()))
                || (c.is_uppercase() && prev.is_uppercase() && next_lower)
                || (c.is_ascii_digit() != prev.is_ascii_digit() && prev.is_alphanumeric());
            if boundary {
                flush(&mut word, &mut words);
            }
        }
        word.extend(c.to_lowercase());
    }
    flush(&mut word, &mut words);
    // `leftarm`, `righthand`: a side glued to a lower-case word.
    words
        .into_iter()
        .flat_map(|w| {
            for side in ["left", "right"] {
                if let Some(rest) = w.strip_prefix(side)
                    && rest.len() > 2
                {
                    return vec![side.to_string(), rest.to_string()];
                }
            }
            vec![w]
        })
        .collect()
}

fn flush(word: &mut String, words: &mut Vec<String>) {
    if !word.is_empty() && !word.chars().all(|c| c.is_ascii_digit()) {
        words.push(std::mem::take(word));
    }
    word.clear();
}

/// Every word a role name is made of: leading words outside it may be dropped (`CC_Base_`), these may not
/// (dropping `Lower` from `LowerArm` would make it an upper arm).
fn known_word(word: &str) -> bool {
    const KNOWN: &[&str] =
        &["upper", "lower", "up", "lo", "low", "fore", "arm", "hand", "back", "neck", "head", "chest", "spine"];
    KNOWN.contains(&word) || SYNONYMS.iter().any(|(_, names)| names.iter().any(|(n, _)| n.contains(word)))
}

fn read_names<S: AsRef<str>>(names: &[S]) -> Vec<Name> {
    let split: Vec<Vec<String>> = names.iter().map(|n| words(n.as_ref())).collect();
    // A prefix of words every bone shares (and that leaves every bone a word) is the rig's, not the bone's.
    let mut shared = 0;
    if split.len() > 1 {
        while split.iter().all(|w| w.len() > shared + 1 && w[shared] == split[0][shared]) {
            shared += 1;
        }
    }
    split.into_iter().map(|w| read_words(&w[shared..])).collect()
}

fn read_words(words: &[String]) -> Name {
    let mut side = None;
    let mut both = false;
    let mut rest = Vec::new();
    let mut refused = false;
    for word in words {
        let w = word.as_str();
        refused |= REFUSED_WORDS.contains(&w) || REFUSED_PARTS.iter().any(|p| w.contains(p));
        let this = if LEFT.contains(&w) {
            Some(Side::Left)
        } else if RIGHT.contains(&w) {
            Some(Side::Right)
        } else {
            None
        };
        match (this, side) {
            (Some(s), None) => side = Some(s),
            (Some(s), Some(t)) if s != t => both = true,
            (Some(_), _) => {}
            (None, _) if FILLER.contains(&w) => {}
            (None, _) => rest.push(w),
        }
    }
    let mut cores = vec![(rest.concat(), 0)];
    for skip in 1..rest.len() {
        if known_word(rest[skip - 1]) {
            break;
        }
        cores.push((rest[skip..].concat(), 1));
    }
    Name { side: if both { None } else { side }, refused, cores }
}

// ---------------------------------------------------------------------------------------------------------
// Role names

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Hips,
    Spine,
    Neck,
    Head,
    Clavicle,
    /// `Shoulder`: a clavicle in segment naming, the upper arm in joint naming.
    ShoulderWord,
    UpperArm,
    Forearm,
    Hand,
    Elbow,
    Wrist,
}

/// Role names with their rank (0 best), compared with a bone's joined words.
const SYNONYMS: &[(Kind, &[(&str, u32)])] = &[
    (Kind::Hips, &[("hips", 0), ("hip", 0), ("pelvis", 0)]),
    (
        Kind::Spine,
        &[
            ("spine", 0),
            ("chest", 0),
            ("upperchest", 0),
            ("lowerback", 0),
            ("back", 0),
            ("torso", 0),
            ("abdomen", 0),
            ("abdomenlower", 0),
            ("abdomenupper", 0),
            ("chestlower", 0),
            ("chestupper", 0),
            ("waist", 0),
            ("belly", 0),
            ("stomach", 0),
            ("lumbar", 0),
            ("thorax", 0),
        ],
    ),
    (Kind::Neck, &[("neck", 0)]),
    (Kind::Head, &[("head", 0)]),
    (Kind::Clavicle, &[("clavicle", 0), ("clav", 0), ("collar", 0), ("collarbone", 0), ("scapula", 0)]),
    (Kind::ShoulderWord, &[("shoulder", 0), ("shldr", 0)]),
    (Kind::UpperArm, &[("upperarm", 0), ("uparm", 0), ("armupper", 0), ("arm", 0), ("humerus", 0), ("shldrbend", 0)]),
    (
        Kind::Forearm,
        &[("forearm", 0), ("lowerarm", 0), ("loarm", 0), ("armlower", 0), ("forearmbend", 0), ("radius", 1)],
    ),
    (Kind::Hand, &[("hand", 0)]),
    (Kind::Elbow, &[("elbow", 0)]),
    (Kind::Wrist, &[("wrist", 0)]),
];

/// The rank of `name` as a `kind` bone (lower is better), or None.
fn rank(name: &Name, kind: Kind) -> Option<u32> {
    if name.refused {
        return None;
    }
    let (_, synonyms) = SYNONYMS.iter().find(|(k, _)| *k == kind)?;
    name.cores
        .iter()
        .filter_map(|(core, penalty)| synonyms.iter().find(|(syn, _)| syn == core).map(|(_, r)| 10 * penalty + r))
        .min()
}

/// How an arm's three bones are named: by segment (`UpperArm`, `ForeArm`, `Hand`) or by joint (`Shoulder`,
/// `Elbow`, `Wrist`). Each entry: the kinds a role accepts, with an added rank.
struct Naming {
    upper: &'static [(Kind, u32)],
    fore: &'static [(Kind, u32)],
    hand: &'static [(Kind, u32)],
    clavicle: &'static [(Kind, u32)],
}

const NAMINGS: [Naming; 2] = [
    Naming {
        upper: &[(Kind::UpperArm, 0)],
        fore: &[(Kind::Forearm, 0)],
        hand: &[(Kind::Hand, 0), (Kind::Wrist, 1)],
        clavicle: &[(Kind::Clavicle, 0), (Kind::ShoulderWord, 1)],
    },
    Naming {
        upper: &[(Kind::ShoulderWord, 0)],
        fore: &[(Kind::Elbow, 0)],
        hand: &[(Kind::Wrist, 0), (Kind::Hand, 1)],
        clavicle: &[(Kind::Clavicle, 0)],
    },
];

// ---------------------------------------------------------------------------------------------------------
// Hierarchy

struct Tree {
    parents: Vec<Option<usize>>,
    depths: Vec<usize>,
}

impl Tree {
    fn new(parents: &[i32]) -> Result<Tree, BoneMapError> {
        let n = parents.len();
        let mut parent_of = Vec::with_capacity(n);
        for (bone, &parent) in parents.iter().enumerate() {
            parent_of.push(match usize::try_from(parent) {
                Ok(p) if p < n && p != bone => Some(p),
                Ok(p) => {
                    return Err(BoneMapError::Malformed(format!("bone {bone} has parent {p} (of {n} bones)")));
                }
                Err(_) if parent == -1 => None,
                Err(_) => return Err(BoneMapError::Malformed(format!("bone {bone} has parent {parent}"))),
            });
        }
        let mut depths = Vec::with_capacity(n);
        for bone in 0..n {
            let mut depth = 0;
            let mut at = bone;
            while let Some(p) = parent_of[at] {
                depth += 1;
                at = p;
                if depth > n {
                    return Err(BoneMapError::Malformed(format!("bone {bone}'s parents loop")));
                }
            }
            depths.push(depth);
        }
        Ok(Tree { parents: parent_of, depths })
    }

    fn len(&self) -> usize {
        self.parents.len()
    }

    /// Whether `ancestor` is a strict ancestor of `bone`.
    fn is_above(&self, ancestor: usize, bone: usize) -> bool {
        self.ancestors(bone).any(|a| a == ancestor)
    }

    /// `bone`'s strict ancestors, nearest first.
    fn ancestors(&self, bone: usize) -> impl Iterator<Item = usize> + '_ {
        std::iter::successors(self.parents[bone], |&b| self.parents[b])
    }

    fn common_ancestor(&self, a: usize, b: usize) -> Option<usize> {
        let above_a: HashSet<usize> = std::iter::once(a).chain(self.ancestors(a)).collect();
        std::iter::once(b).chain(self.ancestors(b)).find(|x| above_a.contains(x))
    }
}

// ---------------------------------------------------------------------------------------------------------
// Matching

struct Matcher {
    tree: Tree,
    words: Vec<Name>,
    names: Vec<String>,
    /// Bones chosen by hand for their roles.
    chosen: Vec<(Role, usize)>,
}

/// Where an arm's search stopped: no upper arm, no forearm below the best upper arm, no hand below the
/// forearm nearest the root.
#[derive(Debug, Clone, Copy)]
enum Lacks {
    UpperArm,
    Forearm { below: usize },
    Hand { below: usize },
}

/// An arm's chain as found, before the chest is known.
#[derive(Debug, Clone, Copy)]
struct Chain {
    naming: usize,
    upper: usize,
    fore: usize,
    hand: usize,
}

impl Matcher {
    fn chosen(&self, role: Role) -> Option<usize> {
        self.chosen.iter().find(|(r, _)| *r == role).map(|&(_, b)| b)
    }

    /// The bones that may hold `role`: the chosen one, else those named like it.
    fn candidates_for(&self, role: Role, side: Option<Side>, kinds: &[(Kind, u32)]) -> Vec<(usize, u32)> {
        match self.chosen(role) {
            Some(bone) => vec![(bone, 0)],
            None => self.candidates(side, kinds),
        }
    }

    fn misplaced(&self, role: Role, bone: usize, reason: String) -> BoneMapError {
        BoneMapError::Misplaced { role, name: self.names[bone].clone(), reason }
    }

    fn candidates(&self, side: Option<Side>, kinds: &[(Kind, u32)]) -> Vec<(usize, u32)> {
        (0..self.tree.len())
            .filter(|&b| self.words[b].side == side)
            .filter_map(|b| {
                kinds.iter().filter_map(|&(k, extra)| rank(&self.words[b], k).map(|r| r + extra)).min().map(|r| (b, r))
            })
            .collect()
    }

    /// The best upper arm > forearm > hand chain of one side in one naming (best names, then the bones nearest
    /// the root), or where the search stopped.
    fn chain(&self, side: Side, naming: usize) -> Result<Chain, Lacks> {
        let n = &NAMINGS[naming];
        let uppers = self.candidates_for(Role::UpperArm(side), Some(side), n.upper);
        let fores = self.candidates_for(Role::Forearm(side), Some(side), n.fore);
        let hands = self.candidates_for(Role::Hand(side), Some(side), n.hand);
        let depth = |b: usize| self.tree.depths[b];
        let mut best: Option<((u32, usize, usize, usize), Chain)> = None;
        let mut stop = match uppers.iter().min_by_key(|&&(b, r)| (r, depth(b), b)) {
            Some(&(upper, _)) => Lacks::Forearm { below: upper },
            None => Lacks::UpperArm,
        };
        for &(upper, ru) in &uppers {
            for &(fore, rf) in fores.iter().filter(|(f, _)| self.tree.is_above(upper, *f)) {
                if !matches!(stop, Lacks::Hand { below } if depth(below) <= depth(fore)) {
                    stop = Lacks::Hand { below: fore };
                }
                for &(hand, rh) in hands.iter().filter(|(h, _)| self.tree.is_above(fore, *h)) {
                    let key = (ru + rf + rh, depth(upper), depth(fore), depth(hand));
                    if best.as_ref().is_none_or(|(k, _)| key < *k) {
                        best = Some((key, Chain { naming, upper, fore, hand }));
                    }
                }
            }
        }
        best.map(|(_, chain)| chain).ok_or(stop)
    }

    /// The arm of one side: segment naming first, then joint naming. A missing role is a `MissingRole`; a chosen
    /// bone that does not fit is an error of its own.
    fn arm(&self, side: Side) -> Result<Chain, Result<MissingRole, BoneMapError>> {
        let segments = match self.chain(side, 0) {
            Ok(chain) => return Ok(chain),
            Err(stop) => stop,
        };
        let joints = match self.chain(side, 1) {
            Ok(chain) => return Ok(chain),
            Err(stop) => stop,
        };
        // Report the segment naming's stop unless the joint naming found more (an Elbow below a Shoulder).
        let stop = match (segments, joints) {
            (Lacks::UpperArm | Lacks::Forearm { .. }, joints @ Lacks::Hand { .. }) => joints,
            (segments, _) => segments,
        };
        let (role, below) = match stop {
            Lacks::UpperArm => (Role::UpperArm(side), None),
            Lacks::Forearm { below } => (Role::Forearm(side), Some(below)),
            Lacks::Hand { below } => (Role::Hand(side), Some(below)),
        };
        if let (Some(bone), Some(below)) = (self.chosen(role), below) {
            return Err(Err(self.misplaced(role, bone, format!("it is not below `{}`", self.names[below]))));
        }
        let mut detail = role.looked_for();
        if let Some(below) = below {
            detail.push_str(&format!("; none below `{}`", self.names[below]));
        }
        Err(Ok(MissingRole { role, detail }))
    }

    fn map(self) -> Result<BoneMap, BoneMapError> {
        let left = self.arm(Side::Left);
        let right = self.arm(Side::Right);
        let (left, right) = match (left, right) {
            (Ok(l), Ok(r)) => (l, r),
            (l, r) => {
                let mut missing = Vec::new();
                for failure in [l.err(), r.err()].into_iter().flatten() {
                    missing.push(failure?);
                }
                if self.candidates(None, &[(Kind::Head, 0)]).is_empty() {
                    missing.push(MissingRole { role: Role::Head, detail: Role::Head.looked_for() });
                }
                return Err(BoneMapError::Missing(missing));
            }
        };
        let above_arms = |b: usize| self.tree.is_above(b, left.upper) && self.tree.is_above(b, right.upper);
        let chest = match self.chosen(Role::Chest) {
            Some(chest) if above_arms(chest) => chest,
            Some(chest) => {
                return Err(self.misplaced(Role::Chest, chest, "it is not above both upper arms".to_string()));
            }
            None => self.tree.common_ancestor(left.upper, right.upper).filter(|&c| above_arms(c)).ok_or_else(|| {
                BoneMapError::Missing(vec![MissingRole {
                    role: Role::Chest,
                    detail: format!("{}; the two upper arms share no ancestor", Role::Chest.looked_for()),
                }])
            })?,
        };
        let hips = match self.chosen(Role::Hips) {
            Some(hips) if self.tree.is_above(hips, chest) => hips,
            Some(hips) => {
                let reason = format!("it is not below the chest `{}`", self.names[chest]);
                return Err(self.misplaced(Role::Hips, hips, reason));
            }
            None => self.hips(chest)?,
        };
        let mut spine: Vec<usize> =
            std::iter::once(chest).chain(self.tree.ancestors(chest).take_while(|&b| b != hips)).collect();
        spine.reverse();
        let head = self.chosen(Role::Head).or_else(|| self.head(hips, chest, &[left.upper, right.upper])).ok_or_else(
            || BoneMapError::Missing(vec![MissingRole { role: Role::Head, detail: Role::Head.looked_for() }]),
        )?;
        // The neck: the `Neck` nearest the root between chest and head, else the first bone on that path.
        let between: Vec<usize> = self.tree.ancestors(head).take_while(|&b| b != hips && !spine.contains(&b)).collect();
        let neck = self.chosen(Role::Neck).or_else(|| {
            between
                .iter()
                .rev()
                .copied()
                .find(|&b| rank(&self.words[b], Kind::Neck).is_some())
                .or_else(|| between.last().copied().filter(|&b| !self.words[b].refused))
        });
        let arm = |chain: Chain, side: Side| -> Result<ArmBones, BoneMapError> {
            let role = Role::Shoulder(side);
            let fits = |b: usize| self.tree.is_above(chest, b) && self.tree.is_above(b, chain.upper);
            let shoulder = self
                .candidates_for(role, Some(side), NAMINGS[chain.naming].clavicle)
                .into_iter()
                .filter(|&(b, _)| fits(b) || self.chosen(role) == Some(b))
                .min_by_key(|&(b, r)| (r, self.tree.depths[b]))
                .map(|(b, _)| b);
            if let Some(bone) = shoulder.filter(|&b| !fits(b)) {
                let reason =
                    format!("it is not between the chest `{}` and the {} upper arm", self.names[chest], side.word());
                return Err(self.misplaced(role, bone, reason));
            }
            Ok(ArmBones { shoulder, upper_arm: chain.upper, forearm: chain.fore, hand: chain.hand })
        };
        Ok(BoneMap { hips, spine, neck, head, left: arm(left, Side::Left)?, right: arm(right, Side::Right)? })
    }

    /// The unsided `Head` nearest the root above the hips and outside the arms; else (Rigify's `spine.006`) the
    /// end of the chain of unsided spine- or neck-named bones above the chest.
    fn head(&self, hips: usize, chest: usize, upper_arms: &[usize]) -> Option<usize> {
        let named = self
            .candidates(None, &[(Kind::Head, 0)])
            .into_iter()
            .filter(|&(b, _)| self.tree.is_above(hips, b) && !upper_arms.iter().any(|&a| self.tree.is_above(a, b)))
            .min_by_key(|&(b, r)| (r, self.tree.depths[b], b))
            .map(|(b, _)| b);
        if named.is_some() {
            return named;
        }
        let spine_or_neck = |b: usize| {
            self.words[b].side.is_none()
                && (rank(&self.words[b], Kind::Spine).or(rank(&self.words[b], Kind::Neck))).is_some()
        };
        let mut at = chest;
        loop {
            let mut next = (0..self.tree.len()).filter(|&b| self.tree.parents[b] == Some(at) && spine_or_neck(b));
            match (next.next(), next.next()) {
                (Some(only), None) => at = only,
                _ => break,
            }
        }
        // A chain that ends in a neck has lost its head.
        (at != chest && rank(&self.words[at], Kind::Neck).is_none()).then_some(at)
    }

    /// The nearest ancestor of the chest named like hips, else the nearest not named like a spine bone, else
    /// the root.
    fn hips(&self, chest: usize) -> Result<usize, BoneMapError> {
        let unsided = |b: &usize| self.words[*b].side.is_none();
        if let Some(hips) =
            self.tree.ancestors(chest).filter(unsided).find(|&b| rank(&self.words[b], Kind::Hips).is_some())
        {
            return Ok(hips);
        }
        let spine_like = |b: usize| rank(&self.words[b], Kind::Spine).is_some();
        self.tree.ancestors(chest).find(|&b| !spine_like(b)).or_else(|| self.tree.ancestors(chest).last()).ok_or_else(
            || {
                BoneMapError::Missing(vec![MissingRole {
                    role: Role::Hips,
                    detail: format!("{}; the chest has no parent", Role::Hips.looked_for()),
                }])
            },
        )
    }
}

#[cfg(test)]
mod tests;
