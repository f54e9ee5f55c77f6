//! Closing a rig's hands into fists: the finger bones below each mapped hand bone bend toward the palm, so the
//! skinned hand shows a fist where the simulated fist is (an open hand's fingers reach 7-10 cm past it).
//!
//! Everything is read from the skeleton's rest, never assumed (bone axes, roll and rest curl differ per rig):
//! - The fingers are the hand bone's descendants, by parentage. A subtree whose bone names say it is no finger
//!   (IK, control, weapon, prop, socket, attachment bones) is left alone. A child of the hand that starts near the
//!   wrist (within a fifth of the forearm, as `skeleton_pose::rig_fist` has it) and has children is a metacarpal:
//!   it keeps its pose and its children start the fingers (MakeHuman, CMU).
//! - The thumb is the subtree with a bone named `thumb` or `pollex`; else, with four or more subtrees, MakeHuman's
//!   `finger1`; else, with four or more, the one pointing furthest from the others' mean direction. A hand with no
//!   such subtree has no thumb.
//! - The hand's direction `d` runs from the wrist (the hand bone's head) to its knuckles (the mean of the finger
//!   roots). The palm faces `n = ∓ d × t` (− for a right hand, + for a left one), where `t` runs across the
//!   hand toward the thumb (along the knuckles, the line through the two finger roots furthest apart, turned
//!   toward the thumb; with one finger, from the knuckles to the thumb): a right hand with its fingers along `d` and its thumb toward `t` has
//!   its palm on that side whatever the rest pose. With no thumb the palm is taken to face down (as in T- and
//!   A-poses), or, with the hand pointing down, toward the body.
//! - Each finger bone bends about `a = dir × n` (its rest direction, head to its children's heads, or for a last
//!   bone its parent's; across the finger and along the palm), which turns the bone toward the palm. The bend
//!   is set absolutely: the angle between the bone and the one before it (about `a`) becomes the fist's, 90, 100
//!   and 70 degrees at the knuckle, middle and last joints (a finger of one bone: 110; of two: 90 and 110; bones
//!   past the third: straight), whatever the rest's own curl. The thumb bends less, by 15, 25 and 30 degrees
//!   more than at rest.
//!
//! The result is each curled bone's local rotation in the fist: the rest's, turned about `a` in the bone's own
//! rest frame, so the finger bends about its own knuckle line and carries its children along. The modifier blends
//! it with the animation's fingers by the punch's blend weight.

use glam::{Quat, Vec3};

use crate::rig::bone_map::{BoneMap, Side};

/// Fist flexion of a finger's joints (degrees, knuckle first) for fingers of three or more bones.
pub const FINGER_FLEXION_DEG: [f32; 3] = [90.0, 100.0, 70.0];
/// The same for a finger of one bone (all fingers in one) and of two.
pub const ONE_BONE_FLEXION_DEG: f32 = 110.0;
pub const TWO_BONE_FLEXION_DEG: [f32; 2] = [90.0, 110.0];
/// How much more than at rest the thumb's bones bend (degrees, from the hand outward).
pub const THUMB_CURL_DEG: [f32; 3] = [15.0, 25.0, 30.0];

/// Words that make a hand's descendant no finger (its subtree is left alone).
const NOT_FINGER: &[&str] = &[
    "ik",
    "fk",
    "ctrl",
    "control",
    "target",
    "pole",
    "weapon",
    "prop",
    "socket",
    "attach",
    "attachment",
    "grip",
    "item",
    "slot",
    "holder",
    "mch",
    "twist",
    "roll",
];

/// One hand's fist.
#[derive(Debug, Clone, PartialEq)]
pub struct HandFist {
    pub side: Side,
    /// The side the palm faces at rest (skeleton space, unit): the fingers fold toward it.
    pub palm: Vec3,
    /// The first bone of the thumb, if one was found.
    pub thumb: Option<usize>,
    /// The first bone of each other finger.
    pub fingers: Vec<usize>,
    /// Each curled bone (parents first) and its local rotation in the fist.
    pub curled: Vec<(usize, Quat)>,
}

/// Both hands' fists (right first); a hand without fingers curls nothing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FistPose {
    pub hands: Vec<HandFist>,
}

impl FistPose {
    /// From a mapped skeleton: bone names, parents (-1 for a root) and every bone's global rest rotation and
    /// position in the skeleton's space.
    pub fn new<S: AsRef<str>>(map: &BoneMap, names: &[S], parents: &[i32], rest: &[(Quat, Vec3)]) -> FistPose {
        if names.len() != rest.len() || parents.len() != rest.len() {
            return FistPose::default();
        }
        let mut children = vec![Vec::new(); rest.len()];
        for (bone, &parent) in parents.iter().enumerate() {
            if let Some(p) = usize::try_from(parent).ok().filter(|&p| p < rest.len()) {
                children[p].push(bone);
            }
        }
        let pos = |b: usize| rest[b].1;
        let up = pos(map.head) - pos(map.hips);
        let left = pos(map.left.upper_arm) - pos(map.right.upper_arm);
        let hands = [Side::Right, Side::Left]
            .into_iter()
            .map(|side| {
                let arm = map.arm(side);
                let inward = if side == Side::Right { left } else { -left };
                hand_fist(names, parents, rest, &children, (arm.hand, arm.forearm), side, (up, inward))
            })
            .collect();
        FistPose { hands }
    }

    /// Every curled bone and its local rotation in the fist.
    pub fn bones(&self) -> impl Iterator<Item = (usize, Quat)> + '_ {
        self.hands.iter().flat_map(|h| h.curled.iter().copied())
    }

    pub fn len(&self) -> usize {
        self.hands.iter().map(|h| h.curled.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A name's lower-case words (split at separators, camelCase and digits).
fn words(name: &str) -> Vec<String> {
    let name = name.rsplit([':', '|']).next().unwrap_or(name);
    let mut words = Vec::new();
    let mut word = String::new();
    let mut prev: Option<char> = None;
    for c in name.chars() {
        let boundary = match prev {
            _ if !c.is_alphanumeric() => true,
            Some(p) => (c.is_uppercase() && p.is_lowercase()) || (c.is_ascii_digit() != p.is_ascii_digit()),
            None => false,
        };
        if boundary && !word.is_empty() {
            words.push(std::mem::take(&mut word));
        }
        if c.is_alphanumeric() {
            word.extend(c.to_lowercase());
        }
        prev = Some(c);
    }
    if !word.is_empty() {
        words.push(word);
    }
    words
}

fn subtree(children: &[Vec<usize>], root: usize) -> Vec<usize> {
    let mut bones = vec![root];
    let mut i = 0;
    while i < bones.len() {
        bones.extend(children[bones[i]].iter().copied());
        i += 1;
    }
    bones
}

/// The index of the thumb among the hand's finger subtrees (see the module's notes).
fn find_thumb<S: AsRef<str>>(
    names: &[S],
    subtrees: &[Vec<usize>],
    rest: &[(Quat, Vec3)],
    wrist: Vec3,
) -> Option<usize> {
    let named = |subtree: &Vec<usize>, test: &dyn Fn(&str) -> bool| {
        subtree.iter().any(|&b| test(&names[b].as_ref().to_lowercase()))
    };
    if let Some(i) = subtrees.iter().position(|s| named(s, &|n| n.contains("thumb") || n.contains("pollex"))) {
        return Some(i);
    }
    if subtrees.len() < 4 {
        return None;
    }
    let finger1 = |s: &Vec<usize>| {
        let w = words(names[s[0]].as_ref());
        w.windows(2).any(|p| p[0] == "finger" && p[1] == "1")
    };
    if subtrees.iter().filter(|s| finger1(s)).count() == 1 {
        return subtrees.iter().position(finger1);
    }
    let direction =
        |s: &Vec<usize>| (s.iter().map(|&b| rest[b].1).sum::<Vec3>() / s.len() as f32 - wrist).normalize_or_zero();
    let directions: Vec<Vec3> = subtrees.iter().map(direction).collect();
    let mean = directions.iter().sum::<Vec3>().normalize_or_zero();
    (0..directions.len()).min_by(|&a, &b| directions[a].dot(mean).total_cmp(&directions[b].dot(mean)))
}

/// The signed angle from `from` to `to` about `axis` (both projected onto the plane across it).
fn angle_about(from: Vec3, to: Vec3, axis: Vec3) -> f32 {
    let f = from - from.dot(axis) * axis;
    let t = to - to.dot(axis) * axis;
    f.cross(t).dot(axis).atan2(f.dot(t))
}

fn hand_fist<S: AsRef<str>>(
    names: &[S],
    parents: &[i32],
    rest: &[(Quat, Vec3)],
    children: &[Vec<usize>],
    (hand, forearm): (usize, usize),
    side: Side,
    (up, inward): (Vec3, Vec3),
) -> HandFist {
    let pos = |b: usize| rest[b].1;
    let wrist = pos(hand);
    let near_m = 0.2 * wrist.distance(pos(forearm));
    let subtrees: Vec<Vec<usize>> = children[hand]
        .iter()
        .filter(|&&c| !words(names[c].as_ref()).iter().any(|w| NOT_FINGER.contains(&w.as_str())))
        .map(|&c| subtree(children, c))
        .collect();
    let thumb = find_thumb(names, &subtrees, rest, wrist);
    // Finger roots: the hand's children, or a metacarpal's children.
    let mut fingers = Vec::new();
    for (i, s) in subtrees.iter().enumerate() {
        let root = s[0];
        if Some(i) == thumb {
            continue;
        }
        if pos(root).distance(wrist) < near_m && !children[root].is_empty() {
            fingers.extend(children[root].iter().copied());
        } else {
            fingers.push(root);
        }
    }
    let empty = HandFist { side, palm: Vec3::ZERO, thumb: thumb.map(|i| subtrees[i][0]), fingers, curled: Vec::new() };
    if empty.fingers.is_empty() {
        return empty;
    }
    let knuckles = empty.fingers.iter().map(|&b| pos(b)).sum::<Vec3>() / empty.fingers.len() as f32;
    let Some(along) = (knuckles - wrist).try_normalize().or_else(|| (wrist - pos(forearm)).try_normalize()) else {
        return empty;
    };
    let across = |v: Vec3| (v - v.dot(along) * along).try_normalize();
    let chirality = if side == Side::Right { -1.0 } else { 1.0 };
    // Across the hand toward the thumb: along the knuckles (their two furthest apart), turned toward the thumb.
    let from_thumb = thumb.and_then(|i| {
        let s = &subtrees[i];
        let centre = s.iter().map(|&b| pos(b)).sum::<Vec3>() / s.len() as f32;
        let toward = across(centre - knuckles)?;
        let fingers = &empty.fingers;
        let line = (0..fingers.len())
            .flat_map(|a| (a + 1..fingers.len()).map(move |b| (a, b)))
            .map(|(a, b)| pos(fingers[a]) - pos(fingers[b]))
            .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
            .and_then(across)
            .filter(|line| line.dot(toward).abs() > 0.5);
        let t = line.map_or(toward, |line| if line.dot(toward) < 0.0 { -line } else { line });
        Some(chirality * along.cross(t))
    });
    let Some(palm) = from_thumb.or_else(|| across(-up)).or_else(|| across(inward)) else {
        return empty;
    };

    let rest_local = |b: usize| match usize::try_from(parents[b]) {
        Ok(p) => (rest[p].0.inverse() * rest[b].0).normalize(),
        Err(_) => rest[b].0.normalize(),
    };
    let incoming =
        |b: usize| usize::try_from(parents[b]).ok().and_then(|p| (pos(b) - pos(p)).try_normalize()).unwrap_or(along);
    let direction = |b: usize| {
        let below = &children[b];
        if below.is_empty() {
            return incoming(b);
        }
        let tip = below.iter().map(|&c| pos(c)).sum::<Vec3>() / below.len() as f32;
        (tip - pos(b)).try_normalize().unwrap_or_else(|| incoming(b))
    };
    let mut curled = Vec::new();
    let mut curl_chain = |root: usize, is_thumb: bool| {
        let bones = subtree(children, root);
        let depth = |mut b: usize| {
            let mut d = 0;
            while b != root {
                b = usize::try_from(parents[b]).unwrap_or(root);
                d += 1;
            }
            d
        };
        let length = bones.iter().map(|&b| depth(b)).max().unwrap_or(0) + 1;
        for b in bones {
            let j = depth(b);
            let dir = direction(b);
            let axis = dir.cross(palm).try_normalize().or_else(|| along.cross(palm).try_normalize());
            let Some(axis) = axis else { continue };
            let bend = if is_thumb {
                THUMB_CURL_DEG.get(j).copied().unwrap_or(0.0).to_radians()
            } else {
                let target = match length {
                    1 => ONE_BONE_FLEXION_DEG,
                    2 => TWO_BONE_FLEXION_DEG[j.min(1)],
                    _ => FINGER_FLEXION_DEG.get(j).copied().unwrap_or(0.0),
                };
                target.to_radians() - angle_about(incoming(b), dir, axis)
            };
            let local_axis = rest[b].0.normalize().inverse() * axis;
            curled.push((b, (rest_local(b) * Quat::from_axis_angle(local_axis, bend)).normalize()));
        }
    };
    if let Some(i) = thumb {
        curl_chain(subtrees[i][0], true);
    }
    for &finger in &empty.fingers {
        curl_chain(finger, false);
    }
    // Parents first (a bone's parent is curled before it, or is not curled at all).
    curled.sort_by_key(|&(b, _)| depth_in(parents, b));
    HandFist { palm, curled, ..empty }
}

fn depth_in(parents: &[i32], mut bone: usize) -> usize {
    let mut depth = 0;
    while let Some(p) = usize::try_from(parents[bone]).ok().filter(|&p| p < parents.len()) {
        bone = p;
        depth += 1;
        if depth > parents.len() {
            break;
        }
    }
    depth
}

#[cfg(test)]
mod tests;
