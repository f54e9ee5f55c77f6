//! Posing a user's rigged skeleton from the simulated upper body (`character::Body`), and blending that pose
//! with the skeleton's animation. `PunchSkeletonModifier` (punch_godot) feeds it the engine's data.
//!
//! Rest frames are read from the skeleton, never assumed: each driven bone's rest direction is the line from its
//! head to its child's head in the global rest (an arm bone along +Y, +X or any roll gives the same result),
//! and the rig's own front comes from its bones: left minus right upper arm is its left, hips to head its up,
//! and their cross product its front. Every driven segment, on the rig and on the simulated body, gets an
//! anatomical frame made of its direction `d` (Y) and a normal `n` (Z) perpendicular to it:
//! - the chest: `d` up, `n` the front (the simulated torso: the character frame, +Y up, +Z ahead);
//! - the upper arm: `d` shoulder to elbow, `n` the side the elbow folds to (on the rig at rest, where arms are
//!   straight in a T- or A-pose, the front, as an elbow bends forward; on the simulated arm, the forearm's
//!   direction, which the 1-DOF elbow keeps fixed in the upper arm's frame);
//! - the forearm: `d` elbow to fist (on the rig, elbow to wrist), `n` the side that faces the upper arm
//!   when the elbow bends (the rig at rest: the front again).
//!
//! A bone's global rotation is then the simulated segment's frame now, times the inverse of the bone's rest
//! frame, times the bone's rest rotation: `G = (Q_body · F_body) · F_rest⁻¹ · R_rest`. So the bone points
//! exactly along the simulated segment, and turns about its own axis as the segment does (a rotation about the
//! bone that keeps the elbow's fold on the side it folds to, whatever axis the rig's bones use). The upper arm
//! and forearm frames differ only by a rotation about the elbow's hinge, so the rig's elbow bends as a hinge
//! too, with no twist between the two bones. Bones between the chest and the upper arm (the clavicle), between
//! the upper arm and forearm, and the hand follow their driving bone rigidly, as in their rest (the
//! simulated torso and forearm are rigid, fist included).
//!
//! The spine: the chest's rotation from the animation's chest to the target is split evenly along the spine
//! chain, as `bone_map::BoneMap::waist_share` says (each of the `n` bones turns by the same `1/n` of it about
//! one global axis; rotations about one axis compose, so the chest lands exactly on its target). The neck and
//! the head keep the animation on the chest, turned by the simulated head's snap on its neck (its rotation away
//! from the chest's, `SkeletonPoser::pose`), shared evenly along the bones from the chest's child to the head
//! in the same way. The hips and legs keep the animation.
//!
//! Blending: the skeleton's local rotations are `slerp(animation, target, w)` with `w` eased in and out
//! (smoothstep of the elapsed fraction of the blend time: no step in the weight, nor in its rate, at either
//! end), so a blend adds no jump to a bone beyond the animation's and the simulation's own motion.

use glam::{Mat3, Quat, Vec3};

use crate::contract::arm_size::ArmLengths;
use crate::contract::character::{Body, JOINTS};
use crate::contract::sensing::CharacterGeometry;
use crate::rig::bone_map::{BoneMap, Side};
use crate::rig::transform::TransformError;

/// Why a skeleton's rest cannot be posed from the simulated body.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PoseError {
    /// The rest pose is degenerate: two bones that set a direction sit at the same place.
    #[error("the skeleton's rest pose is degenerate: {0}")]
    Degenerate(String),
    /// The bone lists do not agree with the map.
    #[error("the skeleton's bone list does not fit its map: {0}")]
    Malformed(String),
    /// A bone the pose is made from has a rest that cannot be read (a NaN, no size: a broken import), by index.
    #[error("bone {bone}'s rest {cause}")]
    BrokenRest { bone: usize, cause: TransformError },
}

/// The first bone whose rest the poser or the fists read and cannot be used, with why: `broken[b]` says what is
/// wrong with bone `b`'s global rest (None: nothing). The bones read are the mapped ones and every bone above them
/// (their rests give the chain's directions and the bones between), and every bone below a hand (the fingers,
/// which say where the fist is). A broken bone elsewhere (a leg, an accessory) does not matter.
pub fn broken_rest(
    map: &BoneMap,
    parents: &[i32],
    broken: &[Option<TransformError>],
) -> Option<(usize, TransformError)> {
    let parent = |b: usize| parents.get(b).and_then(|&p| usize::try_from(p).ok());
    let mapped = [map.hips, map.head].into_iter().chain(map.spine.iter().copied()).chain(map.neck).chain(
        SIDES.iter().flat_map(|&s| {
            let arm = map.arm(s);
            [Some(arm.upper_arm), Some(arm.forearm), Some(arm.hand), arm.shoulder].into_iter().flatten()
        }),
    );
    let mut read = vec![false; broken.len()];
    for bone in mapped {
        // Up to the root (bounded: a cycle in a malformed parent list stops at the bone count).
        let mut at = Some(bone);
        for _ in 0..broken.len() {
            let Some(b) = at.filter(|&b| b < read.len()) else { break };
            read[b] = true;
            at = parent(b);
        }
    }
    let hands = [map.right.hand, map.left.hand];
    for (b, read) in read.iter_mut().enumerate() {
        let mut at = parent(b);
        for _ in 0..broken.len() {
            let Some(p) = at else { break };
            if hands.contains(&p) {
                *read = true;
                break;
            }
            at = parent(p);
        }
    }
    (0..broken.len()).find_map(|b| broken[b].filter(|_| read[b]).map(|cause| (b, cause)))
}

/// An anatomical frame from a direction (its Y) and a normal hint (its Z, made perpendicular). `None` when
/// the direction is zero or along the hint.
pub fn frame(direction: Vec3, hint: Vec3) -> Option<Quat> {
    let y = direction.try_normalize()?;
    let z = (hint - hint.dot(y) * y).try_normalize()?;
    Some(Quat::from_mat3(&Mat3::from_cols(y.cross(z), y, z)).normalize())
}

/// A frame with a fallback hint when the direction lies along the first one.
fn frame_or(direction: Vec3, hint: Vec3, fallback: Vec3, what: &str) -> Result<Quat, PoseError> {
    frame(direction, hint)
        .filter(|_| direction.normalize_or_zero().dot(hint.normalize_or_zero()).abs() < 0.98)
        .or_else(|| frame(direction, fallback))
        .ok_or_else(|| PoseError::Degenerate(what.to_string()))
}

/// The simulated body's anatomical frames in each body's own frame (constant: the bodies are rigid and the
/// elbows are hinges).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyFrames {
    pub torso: Quat,
    /// The head's: the character frame at rest, as the torso's.
    pub head: Quat,
    /// [right, left], as `CharacterGeometry::fist_offsets`.
    pub upper_arm: [Quat; 2],
    pub forearm: [Quat; 2],
    /// Shoulder joints in the character's frame (relative to its root) at rest: [right, left] (`with_shoulders`).
    pub shoulders: [Vec3; 2],
}

impl BodyFrames {
    /// From the character's rest geometry (rest rotations, joint anchors and fist offsets).
    pub fn from_geometry(geometry: &CharacterGeometry) -> Result<BodyFrames, PoseError> {
        let rest = geometry.rest_rotations;
        let torso = rest[Body::Torso.index()].inverse() * geometry.root_rotation;
        let head = rest[Body::Head.index()].inverse() * geometry.root_rotation;
        let mut upper_arm = [Quat::IDENTITY; 2];
        let mut forearm = [Quat::IDENTITY; 2];
        for (side, (upper, fore, shoulder, elbow)) in
            [(Body::UpperArmR, Body::ForearmR, 1, 2), (Body::UpperArmL, Body::ForearmL, 3, 4)].into_iter().enumerate()
        {
            debug_assert!(JOINTS[shoulder].child == upper && JOINTS[elbow].child == fore);
            let (q_u, q_f) = (rest[upper.index()], rest[fore.index()]);
            let shoulder_u = geometry.joint_anchors[shoulder].1;
            let elbow_u = geometry.joint_anchors[elbow].0;
            let elbow_f = geometry.joint_anchors[elbow].1;
            let fist_f = geometry.fist_offsets[side];
            let upper_dir = elbow_u - shoulder_u;
            let fore_dir = fist_f - elbow_f;
            let what = |part: &str| format!("the simulated {part} (its elbow is straight)");
            upper_arm[side] = frame(upper_dir, q_u.inverse() * (q_f * fore_dir)).ok_or_else(|| {
                PoseError::Degenerate(what(if side == 0 { "right upper arm" } else { "left upper arm" }))
            })?;
            forearm[side] = frame(fore_dir, q_f.inverse() * (q_u * -upper_dir))
                .ok_or_else(|| PoseError::Degenerate(what(if side == 0 { "right forearm" } else { "left forearm" })))?;
        }
        Ok(BodyFrames { torso, head, upper_arm, forearm, shoulders: [Vec3::ZERO; 2] })
    }

    /// The same frames with the shoulder joints' rest places (in the character's frame, relative to its root)
    /// given: `CharacterGeometry` does not hold the bodies' positions.
    pub fn with_shoulders(mut self, shoulders: [Vec3; 2]) -> BodyFrames {
        self.shoulders = shoulders;
        self
    }
}

/// How a written bone gets its target global rotation.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Drive {
    /// A spine bone: its share of the chest's turn (index into the chain).
    Spine(usize),
    /// A bone from the chest's child to the head: the animation on its new parent, and its share of the head's snap.
    Neck,
    /// Rigidly with a driving segment, as at rest: `G = G_driver · offset`.
    Follow { driver: Segment, offset: Quat },
    /// A driving segment itself.
    Segment(Segment),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Segment {
    Chest,
    UpperArm(usize),
    Forearm(usize),
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Write {
    bone: usize,
    /// The bone's parent; its new global rotation is known when this bone is written (parents come first),
    /// except for the first spine bone, whose parent (the hips) keeps the animation.
    parent: usize,
    drive: Drive,
}

/// One simulated frame, in the skeleton's space: the rotations of the driving bodies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyRotations {
    pub torso: Quat,
    pub head: Quat,
    /// [right, left].
    pub upper_arm: [Quat; 2],
    pub forearm: [Quat; 2],
}

/// A skeleton mapped to the simulated body: which bones are written, in which order, from what.
#[derive(Debug, Clone, PartialEq)]
pub struct SkeletonPoser {
    writes: Vec<Write>,
    hips: usize,
    spine: Vec<usize>,
    /// How many bones share the head's snap (from the chest's child to the head; 0: the head keeps the animation).
    neck_bones: usize,
    /// `F_rest⁻¹ · R_rest` of the chest, upper arms and forearms ([right, left]).
    chest_offset: Quat,
    upper_offset: [Quat; 2],
    fore_offset: [Quat; 2],
    frames: BodyFrames,
    /// The rig's front-facing frame (character frame to skeleton space: +X its left, +Y up, +Z its front).
    rig_frame: Quat,
    /// The rig's upper arms' heads at rest, in skeleton space: [right, left].
    rig_shoulders: [Vec3; 2],
    upper_arm_bones: [usize; 2],
}

const SIDES: [Side; 2] = [Side::Right, Side::Left];

impl SkeletonPoser {
    /// Maps a skeleton (parents, -1 for a root, and every bone's global rest rotation and position in the
    /// skeleton's space; its fist centres at rest, [right, left], from `rig_fists`) onto the simulated body's frames.
    pub fn new(
        map: &BoneMap,
        parents: &[i32],
        rest: &[(Quat, Vec3)],
        fists: [Vec3; 2],
        frames: BodyFrames,
    ) -> Result<SkeletonPoser, PoseError> {
        if parents.len() != rest.len() {
            return Err(PoseError::Malformed(format!("{} parents but {} rest poses", parents.len(), rest.len())));
        }
        let in_range = |bone: usize| bone < rest.len();
        let all = [map.hips, map.head, map.chest()]
            .into_iter()
            .chain(map.spine.iter().copied())
            .chain(SIDES.iter().flat_map(|&s| [map.arm(s).upper_arm, map.arm(s).forearm, map.arm(s).hand]));
        if let Some(bad) = all.clone().find(|&b| !in_range(b)) {
            return Err(PoseError::Malformed(format!("bone {bad} is out of range")));
        }
        let rot = |b: usize| rest[b].0.normalize();
        let pos = |b: usize| rest[b].1;
        let left = pos(map.left.upper_arm) - pos(map.right.upper_arm);
        let up_raw = pos(map.head) - pos(map.hips);
        let lateral =
            left.try_normalize().ok_or_else(|| PoseError::Degenerate("the two upper arms sit at one place".into()))?;
        let up = (up_raw - up_raw.dot(lateral) * lateral)
            .try_normalize()
            .ok_or_else(|| PoseError::Degenerate("the head is not above the hips".into()))?;
        let front = lateral.cross(up);
        let rig_frame = Quat::from_mat3(&Mat3::from_cols(lateral, up, front)).normalize();
        let chest = map.chest();
        let chest_offset = rig_frame.inverse() * rot(chest);
        let mut upper_offset = [Quat::IDENTITY; 2];
        let mut fore_offset = [Quat::IDENTITY; 2];
        for (i, &side) in SIDES.iter().enumerate() {
            let arm = map.arm(side);
            let what = |part: &str| format!("the {side:?} {part} has no length (its child sits on it)");
            let f_u = frame_or(pos(arm.forearm) - pos(arm.upper_arm), front, -up, &what("upper arm"))?;
            let f_f = frame_or(fists[i] - pos(arm.forearm), front, -up, &what("forearm"))?;
            upper_offset[i] = f_u.inverse() * rot(arm.upper_arm);
            fore_offset[i] = f_f.inverse() * rot(arm.forearm);
        }

        let parent_of = |b: usize| -> Result<usize, PoseError> {
            usize::try_from(parents[b])
                .ok()
                .filter(|&p| in_range(p))
                .ok_or_else(|| PoseError::Malformed(format!("bone {b} has no parent")))
        };
        // The bones strictly between `top` and `bottom`, top first.
        let between = |top: usize, bottom: usize| -> Result<Vec<usize>, PoseError> {
            let mut path = Vec::new();
            let mut bone = parent_of(bottom)?;
            while bone != top {
                path.push(bone);
                bone = parent_of(bone)?;
                if path.len() > rest.len() {
                    return Err(PoseError::Malformed(format!("bone {top} is not above bone {bottom}")));
                }
            }
            path.reverse();
            Ok(path)
        };

        let mut writes = Vec::new();
        for (k, &bone) in map.spine.iter().enumerate() {
            writes.push(Write { bone, parent: parent_of(bone)?, drive: Drive::Spine(k) });
        }
        // The neck and the head, when the head hangs below the chest (a rig whose head is elsewhere keeps its
        // animation's head).
        let neck = between(chest, map.head).map(|path| [path, vec![map.head]].concat()).unwrap_or_default();
        let neck_bones = neck.len();
        for bone in neck {
            writes.push(Write { bone, parent: parent_of(bone)?, drive: Drive::Neck });
        }
        for (i, &side) in SIDES.iter().enumerate() {
            let arm = map.arm(side);
            let chain = [
                (chest, Segment::Chest, arm.upper_arm, Segment::UpperArm(i)),
                (arm.upper_arm, Segment::UpperArm(i), arm.forearm, Segment::Forearm(i)),
            ];
            for (top, top_segment, bottom, bottom_segment) in chain {
                for bone in between(top, bottom)? {
                    let offset = rot(top).inverse() * rot(bone);
                    writes.push(Write {
                        bone,
                        parent: parent_of(bone)?,
                        drive: Drive::Follow { driver: top_segment, offset },
                    });
                }
                writes.push(Write { bone: bottom, parent: parent_of(bottom)?, drive: Drive::Segment(bottom_segment) });
            }
            let mut hand_path = between(arm.forearm, arm.hand)?;
            hand_path.push(arm.hand);
            for bone in hand_path {
                let offset = rot(arm.forearm).inverse() * rot(bone);
                writes.push(Write {
                    bone,
                    parent: parent_of(bone)?,
                    drive: Drive::Follow { driver: Segment::Forearm(i), offset },
                });
            }
        }
        Ok(SkeletonPoser {
            writes,
            hips: map.hips,
            spine: map.spine.clone(),
            neck_bones,
            chest_offset,
            upper_offset,
            fore_offset,
            frames,
            rig_frame,
            rig_shoulders: [pos(map.right.upper_arm), pos(map.left.upper_arm)],
            upper_arm_bones: [map.right.upper_arm, map.left.upper_arm],
        })
    }

    /// The bones this poser writes, parents first.
    pub fn written_bones(&self) -> impl Iterator<Item = usize> + '_ {
        self.writes.iter().map(|w| w.bone)
    }

    /// How many bones it writes.
    pub fn len(&self) -> usize {
        self.writes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.writes.is_empty()
    }

    pub fn hips(&self) -> usize {
        self.hips
    }

    /// The spine chain, from the hips' child up to the chest: the bones whose animated pose `pose` reads.
    pub fn spine(&self) -> &[usize] {
        &self.spine
    }

    /// The first bone of the spine chain (the hips' child).
    pub fn spine_root(&self) -> usize {
        self.spine[0]
    }

    /// The upper arms: (right, left).
    pub fn upper_arms(&self) -> (usize, usize) {
        (self.upper_arm_bones[0], self.upper_arm_bones[1])
    }

    /// The rig's front-facing frame in the skeleton's space (+X its left, +Y up, +Z its front).
    pub fn rig_frame(&self) -> Quat {
        self.rig_frame
    }

    /// Where the simulated character's root goes so that it faces the rig's front (turned about +Y only)
    /// and its shoulder joints' midpoint sits on the rig's (upper arms' heads at rest): `skeleton` is the
    /// skeleton's global rotation and position (`scale` a uniform scale of the skeleton node). Returns the
    /// root's rotation and position.
    pub fn character_placement(&self, skeleton_rotation: Quat, skeleton_origin: Vec3, scale: f32) -> (Quat, Vec3) {
        let front = skeleton_rotation * (self.rig_frame * Vec3::Z);
        let yaw = Quat::from_rotation_y(front.x.atan2(front.z));
        let rig_mid =
            skeleton_origin + skeleton_rotation * (scale * 0.5 * (self.rig_shoulders[0] + self.rig_shoulders[1]));
        let sim_mid = 0.5 * (self.frames.shoulders[0] + self.frames.shoulders[1]);
        (yaw, rig_mid - yaw * sim_mid)
    }

    /// The target local rotation of every written bone (`written_bones` order), from the simulated bodies'
    /// rotations (in the skeleton's space) and the animation's pose: `hips_global`, the hips' global rotation,
    /// and `animated_local(bone)`, a bone's local rotation as the animation left it.
    pub fn pose(&self, bodies: &BodyRotations, hips_global: Quat, animated_local: impl Fn(usize) -> Quat) -> Vec<Quat> {
        let f = &self.frames;
        let chest = bodies.torso * f.torso * self.chest_offset;
        let upper: [Quat; 2] = std::array::from_fn(|i| bodies.upper_arm[i] * f.upper_arm[i] * self.upper_offset[i]);
        let fore: [Quat; 2] = std::array::from_fn(|i| bodies.forearm[i] * f.forearm[i] * self.fore_offset[i]);
        let segment = |s: Segment| match s {
            Segment::Chest => chest,
            Segment::UpperArm(i) => upper[i],
            Segment::Forearm(i) => fore[i],
        };

        // The spine: the animation's chain, then the turn from its chest to the target shared evenly.
        let mut animated_globals = Vec::with_capacity(self.spine.len());
        let mut global = hips_global;
        for &bone in &self.spine {
            global = (global * animated_local(bone)).normalize();
            animated_globals.push(global);
        }
        let mut turn = chest * global.inverse();
        if turn.w < 0.0 {
            turn = -turn;
        }
        let (axis, angle) = turn.to_axis_angle();
        let share = Quat::from_axis_angle(axis, angle / self.spine.len() as f32);
        // The head's snap: its turn away from the chest (both anatomical frames in the skeleton's space), shared
        // evenly by the neck's bones. Each bone turns its animated pose on its new parent by one share about one
        // global axis, so the k-th carries k + 1 shares and the head all of the snap.
        let mut snap = (bodies.head * f.head) * (bodies.torso * f.torso).inverse();
        if snap.w < 0.0 {
            snap = -snap;
        }
        let (snap_axis, snap_angle) = snap.to_axis_angle();
        let neck_share = Quat::from_axis_angle(snap_axis, snap_angle / self.neck_bones.max(1) as f32);

        // New globals of written bones, parents first.
        let mut written: Vec<(usize, Quat)> = Vec::with_capacity(self.writes.len());
        let mut locals = Vec::with_capacity(self.writes.len());
        for write in &self.writes {
            let (local, global) = match write.drive {
                Drive::Spine(k) => {
                    let g = animated_globals[k];
                    let local = (animated_local(write.bone) * (g.inverse() * share * g)).normalize();
                    let parent =
                        if k == 0 { hips_global } else { new_global(&written, write.parent).unwrap_or(hips_global) };
                    (local, (parent * local).normalize())
                }
                Drive::Neck => {
                    let parent = new_global(&written, write.parent).unwrap_or(hips_global);
                    let target = (neck_share * parent * animated_local(write.bone)).normalize();
                    ((parent.inverse() * target).normalize(), target)
                }
                Drive::Follow { driver, offset } => {
                    self.local_for(&written, write.parent, segment(driver) * offset, hips_global)
                }
                Drive::Segment(driver) => self.local_for(&written, write.parent, segment(driver), hips_global),
            };
            written.push((write.bone, global));
            locals.push(local);
        }
        locals
    }

    /// A bone's local rotation that gives it the global rotation `target` under its parent's new global.
    fn local_for(&self, written: &[(usize, Quat)], parent: usize, target: Quat, hips_global: Quat) -> (Quat, Quat) {
        let parent = new_global(written, parent).unwrap_or(hips_global);
        ((parent.inverse() * target).normalize(), target)
    }
}

/// The rig's fist centre at rest (skeleton space): three quarters of the way (`FIST_ALONG_HAND`) from the hand bone's
/// head (the wrist) to its knuckles, the mean of its fingers' roots: where a closed fist's centre is. A finger root is a child of the hand, or, for a child that starts within a fifth
/// of the forearm bone's head from the wrist (a metacarpal or a finger base, as MakeHuman and CMU rigs have), the
/// mean of that child's children. A hand of two roots, one much nearer the wrist than the other, is a thumb and one
/// bone for all four fingers (CMU rigs): the fingers' root then counts four times, as on a hand of five. A hand
/// without children: a quarter of that forearm on past the wrist. The forearm's rest
/// direction is taken toward it, so the visible fist lies on the line of the simulated forearm even when the
/// rig's hand is bent at rest.
pub fn rig_fist(parents: &[i32], rest: &[(Quat, Vec3)], hand: usize, forearm: usize) -> Vec3 {
    let head = rest[hand].1;
    let forearm = rest[forearm].1;
    let near_m = 0.2 * head.distance(forearm);
    let children = |bone: usize| -> Vec<usize> {
        parents.iter().enumerate().filter(|(_, p)| usize::try_from(**p).ok() == Some(bone)).map(|(b, _)| b).collect()
    };
    let roots: Vec<Vec3> = children(hand)
        .into_iter()
        .map(|child| {
            let below = children(child);
            if rest[child].1.distance(head) < near_m && !below.is_empty() {
                below.iter().map(|&b| rest[b].1).sum::<Vec3>() / below.len() as f32
            } else {
                rest[child].1
            }
        })
        .collect();
    if roots.is_empty() {
        return head + 0.25 * (head - forearm);
    }
    let knuckles = match roots[..] {
        // A thumb and one bone for the four fingers (CMU): the fingers' root stands for four, as on a hand of five.
        [a, b] if a.distance(head).min(b.distance(head)) < 0.6 * a.distance(head).max(b.distance(head)) => {
            let (thumb, fingers) = if a.distance(head) < b.distance(head) { (a, b) } else { (b, a) };
            (4.0 * fingers + thumb) / 5.0
        }
        _ => roots.iter().sum::<Vec3>() / roots.len() as f32,
    };
    head + FIST_ALONG_HAND * (knuckles - head)
}

/// How far the fist centre lies from the wrist toward the knuckles (a fraction of that distance). Measured on the
/// converted CC0 characters with their fingers curled into fists (`crate::rig::fist`), skinned at the hit: at three
/// quarters, the skinned fist's front meets the simulated fist's front within 5 mm and its centre is about
/// 1.5 cm further along and 1.8 cm toward the palm; at half, the skin reached 1.5 to 3 cm past the simulated fist.
pub const FIST_ALONG_HAND: f32 = 0.75;

/// The rig's fist centres at rest, [right, left] (skeleton space): `rig_fist`, moved across the hand by its skin
/// (`across_hand_skin`) where `hand_skins` has the hand's skin.
pub fn rig_fists(map: &BoneMap, parents: &[i32], rest: &[(Quat, Vec3)], hand_skins: [&[Vec3]; 2]) -> [Vec3; 2] {
    [0, 1].map(|i| {
        let arm = map.arm(SIDES[i]);
        across_hand_skin(rig_fist(parents, rest, arm.hand, arm.forearm), rest[arm.hand].1, hand_skins[i])
    })
}

/// The fewest skin points (vertices) that say where a hand's middle is.
pub const MIN_HAND_SKIN_POINTS: usize = 16;

/// `fist` (a fist centre found from the bones, `wrist` the hand bone's head) moved across the hand, square to the
/// line from the wrist to it, onto the centre of `hand_skin` (the rest positions of the vertices bound mostly to
/// the hand and the bones below it): its distance along the hand stays the bones'. Bones cannot say where the
/// middle of the knuckles is on a hand whose one finger bone starts at the index finger (CMU rigs), nor how far a
/// thumb's root pulls their mean toward the thumb; the skin can. Fewer than `MIN_HAND_SKIN_POINTS` points (no
/// skinned mesh, or a hand bound to nothing): `fist` as it is.
pub fn across_hand_skin(fist: Vec3, wrist: Vec3, hand_skin: &[Vec3]) -> Vec3 {
    let Some(along) = (fist - wrist).try_normalize() else {
        return fist;
    };
    if hand_skin.len() < MIN_HAND_SKIN_POINTS {
        return fist;
    }
    let centre = hand_skin.iter().sum::<Vec3>() / hand_skin.len() as f32;
    let off = centre - fist;
    fist + off - off.dot(along) * along
}

/// The rig's arm proportions at rest (the mean of its two sides, in the skeleton's units times `scale`): upper
/// arm from its head to the forearm's, forearm from its head to the fist centre (`fists`, [right, left], from
/// `rig_fists`), and the distance between the upper arms' heads.
pub fn rig_arm_lengths(map: &BoneMap, rest: &[(Quat, Vec3)], fists: [Vec3; 2], scale: f32) -> ArmLengths {
    let pos = |b: usize| rest[b].1;
    // The mean of both sides ([right, left], as `fists`).
    let mean = |f: &dyn Fn(usize) -> f32| 0.5 * (f(0) + f(1)) * scale;
    ArmLengths {
        upper_arm_m: mean(&|i| pos(map.arm(SIDES[i]).forearm).distance(pos(map.arm(SIDES[i]).upper_arm))),
        forearm_m: mean(&|i| fists[i].distance(pos(map.arm(SIDES[i]).forearm))),
        shoulder_width_m: scale * pos(map.right.upper_arm).distance(pos(map.left.upper_arm)),
    }
}

/// The fewest skin points (vertices) that say where a head's crown is.
pub const MIN_HEAD_SKIN_POINTS: usize = 16;

/// How high the rig's crown stands above the middle of its upper arms' heads (where the simulated shoulder joints
/// are placed) at rest, along the rig's up (from the hips to the head bone), in the skeleton's units times `scale`:
/// what `PunchCharacter::size_head` takes. The crown is the highest point of `head_skin` (the rest positions of the
/// vertices bound mostly to the head and the bones below it), else the farthest of the head bone's children (a
/// `HeadTop_End`, as Mixamo rigs have); `None` with neither (a head bone alone says nothing of the skull's size).
pub fn rig_shoulder_to_crown(
    map: &BoneMap,
    parents: &[i32],
    rest: &[(Quat, Vec3)],
    head_skin: &[Vec3],
    scale: f32,
) -> Option<f32> {
    let pos = |b: usize| rest[b].1;
    let up = (pos(map.head) - pos(map.hips)).try_normalize()?;
    let shoulders = 0.5 * (pos(map.right.upper_arm) + pos(map.left.upper_arm));
    let height = |p: &Vec3| (*p - shoulders).dot(up);
    let crown = if head_skin.len() >= MIN_HEAD_SKIN_POINTS {
        head_skin.iter().map(height).fold(f32::MIN, f32::max)
    } else {
        let tips = parents.iter().enumerate().filter(|(_, p)| usize::try_from(**p).ok() == Some(map.head));
        tips.map(|(b, _)| height(&pos(b))).reduce(f32::max)?
    };
    (crown > height(&pos(map.head))).then_some(crown * scale)
}

/// The new global rotation of a bone already written (few bones: a linear scan is cheapest).
fn new_global(written: &[(usize, Quat)], bone: usize) -> Option<Quat> {
    written.iter().rev().find(|(b, _)| *b == bone).map(|(_, q)| *q)
}

/// The blend weight between the animation (0) and the simulated body (1), eased in and out.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Blend {
    /// Elapsed fraction of the blend, 0..1.
    progress: f32,
}

impl Blend {
    /// Advances by `delta_s` toward 1 (`active`, over `in_s`) or 0 (over `out_s`) and returns the weight.
    /// A blend time of 0 switches at once.
    pub fn advance(&mut self, active: bool, delta_s: f32, in_s: f32, out_s: f32) -> f32 {
        let step = |time_s: f32| if time_s > 0.0 { delta_s.max(0.0) / time_s } else { 1.0 };
        self.progress =
            if active { (self.progress + step(in_s)).min(1.0) } else { (self.progress - step(out_s)).max(0.0) };
        self.weight()
    }

    /// The weight now: smoothstep of the progress (zero slope at both ends).
    pub fn weight(&self) -> f32 {
        let p = self.progress;
        p * p * (3.0 - 2.0 * p)
    }

    /// Jumps to fully on or off (no blend).
    pub fn set(&mut self, on: bool) {
        self.progress = if on { 1.0 } else { 0.0 };
    }
}

#[cfg(test)]
mod tests;
