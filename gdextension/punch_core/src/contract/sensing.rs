//! Per-physics-frame sensing: what the character and the bag did in one frame, in the character's frame,
//! as a flat feature vector (rewards are written over these features). The exploit guard flags frames
//! with non-physical events so that rewards can ignore them.

use glam::{Quat, Vec3};

use crate::contract::arm_size::ArmLengths;
use crate::contract::character::{BODY_COUNT, Body, DOF_COUNT, DOFS, JOINTS, PHYSICS_HZ, dof_angles, joint_rotation};

/// State of one rigid body in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyState {
    pub position: Vec3,
    pub rotation: Quat,
    pub linear_velocity: Vec3,
    pub angular_velocity: Vec3,
}

/// Most contacts the engine reports on the bag per step (its `max_contacts_reported`).
pub const MAX_BAG_CONTACTS: usize = 8;

/// How far beyond the fist's surface a contact point on a forearm still counts as the fist's, m.
pub const FIST_CONTACT_MARGIN_M: f32 = 0.02;

/// One contact on the bag from a body of the character, as the engine reported it (world coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BagContact {
    /// Index into `Body::ALL` of the character's body.
    pub body: usize,
    pub point: Vec3,
    /// Impulse applied to the bag, N s.
    pub impulse: Vec3,
}

/// Everything read from the engine for one frame (world coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameReading {
    /// Bodies in `Body::ALL` order.
    pub bodies: [BodyState; BODY_COUNT],
    pub bag: BodyState,
    /// The character's contacts on the bag this frame: the first `contact_count` entries.
    pub contacts: [BagContact; MAX_BAG_CONTACTS],
    pub contact_count: usize,
}

/// Geometry fixed for a character instance, read from its scene once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CharacterGeometry {
    /// World rotation of each body in the rest pose (`Body::ALL` order).
    pub rest_rotations: [Quat; BODY_COUNT],
    /// Fist centres in the forearm's local frame: [right, left].
    pub fist_offsets: [Vec3; 2],
    pub fist_radius_m: f32,
    /// Joint anchor in the parent's and the child's local frames (`JOINTS` order).
    pub joint_anchors: [(Vec3, Vec3); 5],
    pub bag_radius_m: f32,
    pub bag_height_m: f32,
    pub bag_mass_kg: f32,
    /// World transform of the character's root in the rest pose. The pelvis carries the root (it is kinematic,
    /// moved with the character), so each frame the root is where the pelvis now says (`Sensor::root_now`).
    pub root_rotation: Quat,
    pub root_position: Vec3,
    /// World position of the pelvis in the rest pose (with `rest_rotations[Pelvis]`, the pelvis's rest place).
    pub pelvis_rest_position: Vec3,
}

impl CharacterGeometry {
    /// Where `position` (global) lies in the root's frame: +Z ahead, +Y up, +X the character's left.
    pub fn root_local(&self, position: Vec3) -> Vec3 {
        self.root_rotation.inverse() * (position - self.root_position)
    }

    /// The right arm's lengths and the shoulders' distance, from the joint anchors and the fist: the body's
    /// size as the policy observes it (`body_*` features), so one policy can punch with arms sized to any rig.
    pub fn arm_lengths(&self) -> ArmLengths {
        let [_, shoulder_r, elbow_r, shoulder_l, _] = self.joint_anchors;
        ArmLengths {
            // Both anchors of a pair in the upper arm's frame (the shoulder's child, the elbow's parent).
            upper_arm_m: elbow_r.0.distance(shoulder_r.1),
            forearm_m: self.fist_offsets[0].distance(elbow_r.1),
            // Both shoulders' anchors in the torso's frame.
            shoulder_width_m: shoulder_r.0.distance(shoulder_l.0),
        }
    }
}

/// Guard flags (bits of the `exploit_flags` feature).
pub mod guard {
    /// A fist moves faster than the drives can make it (human punches peak near 12 m/s).
    pub const FIST_TOO_FAST: u32 = 1 << 0;
    /// A joint's two anchors drifted apart: the constraint was violated.
    pub const JOINT_SEPARATED: u32 = 1 << 1;
    /// A fist is deep inside the bag.
    pub const PENETRATION: u32 = 1 << 2;
    /// A body's velocity jumped with no contact on the bag to explain it (a body snapping back into place).
    pub const VELOCITY_JUMP: u32 = 1 << 3;

    pub const FIST_SPEED_LIMIT_MPS: f32 = 15.0;
    /// Jolt's joints stretch transiently under violent motion (measured worst case about 2.4 cm under random
    /// +-1 actions flipping every 42 ms, and under 0.5 mm in ordinary motion); beyond 3 cm a joint failed.
    pub const JOINT_SEPARATION_LIMIT_M: f32 = 0.03;
    pub const PENETRATION_LIMIT_M: f32 = 0.03;
    /// Largest velocity change in one frame (m/s) that the drives can cause without a contact (about 60 g).
    pub const VELOCITY_JUMP_LIMIT_MPS: f32 = 10.0;
    /// Contact impulse (N s) below which the character counts as not touching the bag.
    pub const CONTACT_IMPULSE_EPSILON: f32 = 1e-3;
}

/// Gravity the simulation uses, m/s^2 (Godot's default 3D gravity).
pub const GRAVITY_MPS2: f32 = 9.8;

/// Names of the per-frame features, in order.
pub const FEATURE_NAMES: [&str; FEATURE_COUNT] = [
    "fist_r_pos_x",
    "fist_r_pos_y",
    "fist_r_pos_z",
    "fist_r_vel_x",
    "fist_r_vel_y",
    "fist_r_vel_z",
    "fist_l_pos_x",
    "fist_l_pos_y",
    "fist_l_pos_z",
    "fist_l_vel_x",
    "fist_l_vel_y",
    "fist_l_vel_z",
    "fist_r_impulse_x",
    "fist_r_impulse_y",
    "fist_r_impulse_z",
    "fist_l_impulse_x",
    "fist_l_impulse_y",
    "fist_l_impulse_z",
    "character_impulse_x",
    "character_impulse_y",
    "character_impulse_z",
    "bag_pos_x",
    "bag_pos_y",
    "bag_pos_z",
    "bag_vel_x",
    "bag_vel_y",
    "bag_vel_z",
    "bag_momentum_change_x",
    "bag_momentum_change_y",
    "bag_momentum_change_z",
    "fist_r_bag_distance",
    "fist_l_bag_distance",
    "angle_waist_flexion",
    "angle_waist_rotation",
    "angle_shoulder_r_flexion",
    "angle_shoulder_r_rotation",
    "angle_shoulder_r_abduction",
    "angle_elbow_r_extension",
    "angle_shoulder_l_flexion",
    "angle_shoulder_l_rotation",
    "angle_shoulder_l_abduction",
    "angle_elbow_l_extension",
    "speed_waist_flexion",
    "speed_waist_rotation",
    "speed_shoulder_r_flexion",
    "speed_shoulder_r_rotation",
    "speed_shoulder_r_abduction",
    "speed_elbow_r_extension",
    "speed_shoulder_l_flexion",
    "speed_shoulder_l_rotation",
    "speed_shoulder_l_abduction",
    "speed_elbow_l_extension",
    "root_vel_x",
    "root_vel_y",
    "root_vel_z",
    "root_spin_x",
    "root_spin_y",
    "root_spin_z",
    "body_upper_arm_m",
    "body_forearm_m",
    "body_shoulder_width_m",
    "joint_gap_max_m",
    "exploit_flags",
];
pub const FEATURE_COUNT: usize = 63;

/// First column of some three-component features (x, y, z follow), for code that reads them every frame.
pub mod columns {
    pub const FIST_R_VEL: usize = 3;
    pub const FIST_L_VEL: usize = 9;
    pub const FIST_R_IMPULSE: usize = 12;
    pub const FIST_L_IMPULSE: usize = 15;
    /// The 10 joint angles (rad), then the 10 joint speeds (rad/s), in action order.
    pub const ANGLES: usize = 32;
    pub const SPEEDS: usize = 42;
    /// The root's velocity (m/s), then its angular velocity (rad/s), in its own frame.
    pub const ROOT_VEL: usize = 52;
    pub const ROOT_SPIN: usize = 55;
    /// The character's arm lengths (m): upper arm, elbow to fist centre, shoulder to shoulder.
    pub const BODY_SIZE: usize = 58;
}

/// The three components starting at `column` as a vector.
pub fn feature_vector(features: &[f32; FEATURE_COUNT], column: usize) -> Vec3 {
    Vec3::new(features[column], features[column + 1], features[column + 2])
}

/// Index of a feature by name.
pub fn feature_index(name: &str) -> Option<usize> {
    FEATURE_NAMES.iter().position(|n| *n == name)
}

/// Turns engine readings into features, frame after frame (it remembers the previous frame for velocity
/// jumps and the bag's momentum change).
#[derive(Debug, Clone)]
pub struct Sensor {
    geometry: CharacterGeometry,
    /// The geometry's arm lengths (the `body_*` features), read once: they hold for the whole punch.
    arms: ArmLengths,
    previous: Option<FrameReading>,
}

impl Sensor {
    pub fn new(geometry: CharacterGeometry) -> Self {
        Self { arms: geometry.arm_lengths(), geometry, previous: None }
    }

    pub fn geometry(&self) -> &CharacterGeometry {
        &self.geometry
    }

    /// Forgets the previous frame (call at episode reset).
    pub fn reset(&mut self) {
        self.previous = None;
    }

    /// Joint rotations (child frame relative to parent frame) of a reading, in `JOINTS` order, in the joint
    /// frames: these are aligned with the character's root frame in the rest pose, so a rotation measured in
    /// world axes is turned into the root's axes (a character facing any way reads the same angles).
    pub fn joint_rotations(&self, reading: &FrameReading) -> [Quat; 5] {
        let rest = &self.geometry.rest_rotations;
        let root = self.geometry.root_rotation;
        std::array::from_fn(|j| {
            let (p, c) = (JOINTS[j].parent.index(), JOINTS[j].child.index());
            let in_world_axes =
                joint_rotation(reading.bodies[p].rotation, rest[p], reading.bodies[c].rotation, rest[c]);
            root.inverse() * in_world_axes * root
        })
    }

    /// World positions and velocities of the fists: [(position, velocity); right, left].
    pub fn fists(&self, reading: &FrameReading) -> [(Vec3, Vec3); 2] {
        std::array::from_fn(|side| {
            let body = &reading.bodies[[Body::ForearmR, Body::ForearmL][side].index()];
            let arm = body.rotation * self.geometry.fist_offsets[side];
            (body.position + arm, body.linear_velocity + body.angular_velocity.cross(arm))
        })
    }

    /// The character's root now (world rotation, position): the pelvis is moved with the root, so the root is
    /// where the pelvis's rest offset puts it. A pelvis exactly at rest gives the rest root unchanged.
    pub fn root_now(&self, reading: &FrameReading) -> (Quat, Vec3) {
        let g = &self.geometry;
        let pelvis = &reading.bodies[Body::Pelvis.index()];
        let rest_rotation = g.rest_rotations[Body::Pelvis.index()];
        if pelvis.rotation == rest_rotation && pelvis.position == g.pelvis_rest_position {
            return (g.root_rotation, g.root_position);
        }
        let turn = (pelvis.rotation * rest_rotation.inverse()).normalize();
        (turn * g.root_rotation, pelvis.position + turn * (g.root_position - g.pelvis_rest_position))
    }

    /// Features of one frame (see `FEATURE_NAMES`), in the frame of the character's root as it is now.
    /// Velocities are the world's (a fist's includes its body's walking), expressed in the root's axes.
    pub fn features(&mut self, reading: &FrameReading) -> [f32; FEATURE_COUNT] {
        let (root_rotation, root_position) = self.root_now(reading);
        let to_local_rotation = root_rotation.inverse();
        let local_point = |p: Vec3| to_local_rotation * (p - root_position);
        let local_vector = |v: Vec3| to_local_rotation * v;
        let g = &self.geometry;
        let pelvis = &reading.bodies[Body::Pelvis.index()];
        let root_velocity = pelvis.linear_velocity + pelvis.angular_velocity.cross(root_position - pelvis.position);

        let fists = self.fists(reading);
        let bag_position = reading.bag.position;
        let dt = 1.0 / PHYSICS_HZ as f32;
        let bag_momentum_change = match &self.previous {
            Some(previous) => {
                g.bag_mass_kg * (reading.bag.linear_velocity - previous.bag.linear_velocity)
                    + g.bag_mass_kg * GRAVITY_MPS2 * dt * Vec3::Y
            }
            None => Vec3::ZERO,
        };

        let (fist_impulses, character_impulse) = self.contact_impulses(reading, &fists);
        let rotations = self.joint_rotations(reading);
        let angles = dof_angles(&rotations);
        let speeds = self.joint_speeds(reading);
        let joint_gap = self.largest_joint_gap(reading);
        let touching = character_impulse.length() > guard::CONTACT_IMPULSE_EPSILON;
        let flags = self.exploit_flags(reading, &fists, joint_gap, touching);

        let mut out = [0.0f32; FEATURE_COUNT];
        let mut cursor = 0;
        let mut push = |values: &[f32]| {
            out[cursor..cursor + values.len()].copy_from_slice(values);
            cursor += values.len();
        };
        for (position, velocity) in fists {
            push(&local_point(position).to_array());
            push(&local_vector(velocity).to_array());
        }
        for impulse in fist_impulses {
            push(&local_vector(impulse).to_array());
        }
        push(&local_vector(character_impulse).to_array());
        push(&local_point(bag_position).to_array());
        push(&local_vector(reading.bag.linear_velocity).to_array());
        push(&local_vector(bag_momentum_change).to_array());
        push(&[fists[0].0.distance(bag_position), fists[1].0.distance(bag_position)]);
        push(&angles);
        push(&speeds);
        push(&local_vector(root_velocity).to_array());
        push(&local_vector(pelvis.angular_velocity).to_array());
        push(&[self.arms.upper_arm_m, self.arms.forearm_m, self.arms.shoulder_width_m]);
        push(&[joint_gap, flags as f32]);
        debug_assert_eq!(cursor, FEATURE_COUNT);
        self.previous = Some(*reading);
        out
    }

    /// Joint angular speeds (rad/s) about each DOF axis, in the parent joint frame.
    fn joint_speeds(&self, reading: &FrameReading) -> [f32; DOF_COUNT] {
        let rest = &self.geometry.rest_rotations;
        let root = self.geometry.root_rotation;
        std::array::from_fn(|i| {
            let joint = &JOINTS[DOFS[i].joint];
            let (p, c) = (joint.parent.index(), joint.child.index());
            let parent_frame = reading.bodies[p].rotation * rest[p].inverse();
            let relative = reading.bodies[c].angular_velocity - reading.bodies[p].angular_velocity;
            // In the parent joint frame, whose rest orientation is the root's.
            (root.inverse() * (parent_frame.inverse() * relative))[DOFS[i].axis.index()]
        })
    }

    /// Impulses on the bag this frame: by each fist (a forearm contact within the fist's radius plus a
    /// margin of the fist's centre), and by the whole character.
    fn contact_impulses(&self, reading: &FrameReading, fists: &[(Vec3, Vec3); 2]) -> ([Vec3; 2], Vec3) {
        let mut by_fist = [Vec3::ZERO; 2];
        let mut total = Vec3::ZERO;
        let reach = self.geometry.fist_radius_m + FIST_CONTACT_MARGIN_M;
        for contact in &reading.contacts[..reading.contact_count.min(MAX_BAG_CONTACTS)] {
            total += contact.impulse;
            for (side, forearm) in [Body::ForearmR, Body::ForearmL].into_iter().enumerate() {
                if contact.body == forearm.index() && contact.point.distance(fists[side].0) <= reach {
                    by_fist[side] += contact.impulse;
                }
            }
        }
        (by_fist, total)
    }

    /// Largest distance (m) between a joint's anchor as seen from its parent and from its child.
    fn largest_joint_gap(&self, reading: &FrameReading) -> f32 {
        JOINTS
            .iter()
            .zip(&self.geometry.joint_anchors)
            .map(|(joint, (parent_anchor, child_anchor))| {
                let parent = &reading.bodies[joint.parent.index()];
                let child = &reading.bodies[joint.child.index()];
                ((parent.position + parent.rotation * *parent_anchor)
                    - (child.position + child.rotation * *child_anchor))
                    .length()
            })
            .fold(0.0, f32::max)
    }

    fn exploit_flags(&self, reading: &FrameReading, fists: &[(Vec3, Vec3); 2], joint_gap: f32, touching: bool) -> u32 {
        let g = &self.geometry;
        let mut flags = 0;
        if fists.iter().any(|(_, velocity)| velocity.length() > guard::FIST_SPEED_LIMIT_MPS) {
            flags |= guard::FIST_TOO_FAST;
        }
        if joint_gap > guard::JOINT_SEPARATION_LIMIT_M {
            flags |= guard::JOINT_SEPARATED;
        }
        let bag_rotation = reading.bag.rotation.inverse();
        for (position, _) in fists {
            let local = bag_rotation * (*position - reading.bag.position);
            let radial = Vec3::new(local.x, 0.0, local.z).length();
            let inside_height = local.y.abs() < g.bag_height_m / 2.0;
            let depth = g.bag_radius_m + g.fist_radius_m - radial;
            if inside_height && depth > g.fist_radius_m + guard::PENETRATION_LIMIT_M {
                flags |= guard::PENETRATION;
            }
        }
        if let Some(previous) = &self.previous {
            let jumped = |now: &BodyState, before: &BodyState| {
                (now.linear_velocity - before.linear_velocity).length() > guard::VELOCITY_JUMP_LIMIT_MPS
            };
            let body_jump = reading.bodies.iter().zip(&previous.bodies).any(|(now, before)| jumped(now, before));
            if !touching && (body_jump || jumped(&reading.bag, &previous.bag)) {
                flags |= guard::VELOCITY_JUMP;
            }
        }
        flags
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fake_world::rest_geometry;

    fn reading_at_rest() -> FrameReading {
        let mut reading = FrameReading::default();
        for body in &mut reading.bodies {
            body.rotation = Quat::IDENTITY;
        }
        reading.bag.rotation = Quat::IDENTITY;
        reading.bag.position = Vec3::new(0.0, 1.35, 0.72);
        reading
    }

    #[test]
    fn names_are_unique_and_counted() {
        let mut names = FEATURE_NAMES.to_vec();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), FEATURE_COUNT);
        assert_eq!(feature_index("exploit_flags"), Some(FEATURE_COUNT - 1), "the session reads flags from the end");
        for (column, name) in [
            (columns::FIST_R_VEL, "fist_r_vel_x"),
            (columns::FIST_L_VEL, "fist_l_vel_x"),
            (columns::FIST_R_IMPULSE, "fist_r_impulse_x"),
            (columns::FIST_L_IMPULSE, "fist_l_impulse_x"),
            (columns::ANGLES, "angle_waist_flexion"),
            (columns::SPEEDS, "speed_waist_flexion"),
            (columns::ROOT_VEL, "root_vel_x"),
            (columns::ROOT_SPIN, "root_spin_x"),
            (columns::BODY_SIZE, "body_upper_arm_m"),
        ] {
            assert_eq!(feature_index(name), Some(column), "{name}");
        }
    }

    #[test]
    fn the_body_size_features_are_the_arm_lengths_of_the_geometry() {
        // Shoulders 0.36 m apart on the torso; the upper arm's anchors 0.28 m apart; elbow to fist 0.34 m.
        let mut geometry = rest_geometry();
        geometry.joint_anchors[1] = (Vec3::new(-0.18, 0.3, 0.0), Vec3::new(0.0, 0.14, 0.0));
        geometry.joint_anchors[2] = (Vec3::new(0.0, -0.14, 0.0), Vec3::new(0.0, 0.1, 0.0));
        geometry.joint_anchors[3] = (Vec3::new(0.18, 0.3, 0.0), Vec3::new(0.0, 0.14, 0.0));
        geometry.fist_offsets[0] = Vec3::new(0.0, -0.24, 0.0);
        let features = Sensor::new(geometry).features(&reading_at_rest());
        let sizes = feature_vector(&features, columns::BODY_SIZE);
        assert!((sizes - Vec3::new(0.28, 0.34, 0.36)).length() < 1e-6, "{sizes}");
    }

    #[test]
    fn at_rest_every_motion_feature_is_zero() {
        let mut sensor = Sensor::new(rest_geometry());
        let features = sensor.features(&reading_at_rest());
        for (name, value) in FEATURE_NAMES.iter().zip(features) {
            if name.contains("vel")
                || name.contains("impulse")
                || name.starts_with("angle")
                || name.starts_with("speed")
                || *name == "exploit_flags"
            {
                assert_eq!(value, 0.0, "{name}");
            }
        }
    }

    #[test]
    fn fist_velocity_includes_rotation() {
        let mut reading = reading_at_rest();
        reading.bodies[Body::ForearmR.index()].angular_velocity = Vec3::new(10.0, 0.0, 0.0);
        let sensor = Sensor::new(rest_geometry());
        let [(_, velocity), _] = sensor.fists(&reading);
        // omega x r = (10,0,0) x (0,-0.155,0) = (0, 0, -1.55)
        assert!((velocity - Vec3::new(0.0, 0.0, -1.55)).length() < 1e-5);
    }

    #[test]
    fn bag_momentum_change_cancels_gravity() {
        let mut sensor = Sensor::new(rest_geometry());
        let mut reading = reading_at_rest();
        sensor.features(&reading);
        // Free fall for one frame: no impulse other than gravity acted.
        reading.bag.linear_velocity = Vec3::new(0.0, -GRAVITY_MPS2 / PHYSICS_HZ as f32, 0.0);
        let features = sensor.features(&reading);
        let y = feature_index("bag_momentum_change_y").expect("feature");
        assert!(features[y].abs() < 1e-4, "{}", features[y]);
    }

    #[test]
    fn features_are_in_the_root_frame() {
        let mut geometry = rest_geometry();
        geometry.root_rotation = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        geometry.root_position = Vec3::new(5.0, 0.0, 0.0);
        let mut sensor = Sensor::new(geometry);
        let mut reading = reading_at_rest();
        // Root turned 90 degrees left: its forward (+Z) is world +X.
        reading.bag.position = Vec3::new(5.72, 1.35, 0.0);
        let features = sensor.features(&reading);
        let z = feature_index("bag_pos_z").expect("feature");
        assert!((features[z] - 0.72).abs() < 1e-5);
    }

    #[test]
    fn a_turned_and_moved_character_senses_what_it_senses_at_the_origin() {
        // A pose with every joint bent and turning, at the origin facing +Z...
        let mut reading = reading_at_rest();
        for (i, body) in reading.bodies.iter_mut().enumerate() {
            body.rotation = Quat::from_euler(glam::EulerRot::YXZ, 0.1 * i as f32, -0.2 * i as f32, 0.05 * i as f32);
            body.position = Vec3::new(0.02 * i as f32, 1.2 + 0.05 * i as f32, 0.03 * i as f32);
            body.linear_velocity = Vec3::new(0.3, -0.1 * i as f32, 1.5);
            body.angular_velocity = Vec3::new(0.5 * i as f32, -1.0, 0.25 * i as f32);
        }
        let at_origin = Sensor::new(rest_geometry()).features(&reading);
        // ...and the same pose with the whole character turned (yaw 90 and 180 degrees, and a tilt) and moved.
        for turn in [
            Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            Quat::from_rotation_y(std::f32::consts::PI),
            Quat::from_rotation_y(-0.7) * Quat::from_rotation_x(0.2),
        ] {
            let offset = Vec3::new(5.0, 0.5, -3.0);
            let mut geometry = rest_geometry();
            geometry.rest_rotations = geometry.rest_rotations.map(|rest| turn * rest);
            geometry.root_rotation = turn;
            geometry.root_position = offset;
            geometry.pelvis_rest_position = offset + turn * geometry.pelvis_rest_position;
            let mut turned = reading;
            for body in turned.bodies.iter_mut().chain([&mut turned.bag]) {
                *body = BodyState {
                    position: offset + turn * body.position,
                    rotation: turn * body.rotation,
                    linear_velocity: turn * body.linear_velocity,
                    angular_velocity: turn * body.angular_velocity,
                };
            }
            let features = Sensor::new(geometry).features(&turned);
            for (name, (a, b)) in FEATURE_NAMES.iter().zip(at_origin.iter().zip(&features)) {
                assert!((a - b).abs() < 1e-4, "{name}: {a} at the origin, {b} turned by {turn:?}");
            }
        }
    }

    #[test]
    fn a_carried_character_senses_in_the_frame_of_its_root_now_and_its_own_motion() {
        // A pose at rest where the punch started...
        let mut reading = reading_at_rest();
        for (i, body) in reading.bodies.iter_mut().enumerate() {
            body.position = Vec3::new(0.02 * i as f32, 1.0 + 0.05 * i as f32, 0.03 * i as f32);
        }
        let mut sensor =
            Sensor::new(CharacterGeometry { pelvis_rest_position: reading.bodies[0].position, ..rest_geometry() });
        let standing = sensor.features(&reading);
        // ...and the same pose carried: the whole body turned 40 degrees left and 0.5 m on, walking ahead at
        // 1.4 m/s while turning at 2 rad/s (every body moving rigidly with the root).
        let (turn, offset) = (Quat::from_rotation_y(0.7), Vec3::new(0.3, 0.0, 0.4));
        let (walk, spin) = (turn * Vec3::new(0.0, 0.0, 1.4), Vec3::new(0.0, 2.0, 0.0));
        let mut carried = reading;
        for body in carried.bodies.iter_mut().chain([&mut carried.bag]) {
            let position = offset + turn * body.position;
            *body = BodyState {
                position,
                rotation: turn * body.rotation,
                linear_velocity: walk + spin.cross(position - offset),
                angular_velocity: spin,
            };
        }
        sensor.reset();
        let features = sensor.features(&carried);
        for (i, name) in FEATURE_NAMES.iter().enumerate() {
            if name.contains("_pos_") || name.starts_with("angle") || name.starts_with("speed") {
                assert!(
                    (features[i] - standing[i]).abs() < 1e-4,
                    "{name}: {} standing, {} carried",
                    standing[i],
                    features[i]
                );
            }
        }
        let root_velocity = feature_vector(&features, columns::ROOT_VEL);
        assert!((root_velocity - Vec3::new(0.0, 0.0, 1.4)).length() < 1e-4, "{root_velocity}");
        assert!((feature_vector(&features, columns::ROOT_SPIN) - spin).length() < 1e-5);
        assert_eq!(feature_vector(&standing, columns::ROOT_VEL), Vec3::ZERO);
    }

    #[test]
    fn guard_flags_fast_fists_separated_joints_penetration_and_jumps() {
        let mut sensor = Sensor::new(rest_geometry());
        let flags_index = feature_index("exploit_flags").expect("feature");
        let mut reading = reading_at_rest();
        assert_eq!(sensor.features(&reading)[flags_index], 0.0);

        let mut fast = reading;
        fast.bodies[Body::ForearmR.index()].linear_velocity = Vec3::new(0.0, 0.0, 20.0);
        let flags = sensor.features(&fast)[flags_index] as u32;
        assert_ne!(flags & guard::FIST_TOO_FAST, 0);
        assert_ne!(flags & guard::VELOCITY_JUMP, 0, "20 m/s in one frame with no contact");

        sensor.reset();
        let mut separated = reading;
        separated.bodies[Body::ForearmL.index()].position = Vec3::new(0.0, 0.0, 0.1);
        assert_ne!(sensor.features(&separated)[flags_index] as u32 & guard::JOINT_SEPARATED, 0);

        sensor.reset();
        // Right fist centre 5 cm inside the bag's axis region.
        reading.bodies[Body::ForearmR.index()].position = reading.bag.position + Vec3::new(0.0, 0.155, -0.05);
        assert_ne!(sensor.features(&reading)[flags_index] as u32 & guard::PENETRATION, 0);
    }

    #[test]
    fn only_contacts_at_the_fist_count_as_the_fists() {
        let mut sensor = Sensor::new(rest_geometry());
        let mut reading = reading_at_rest();
        let fist = sensor.fists(&reading)[0].0;
        let forearm = Body::ForearmR.index();
        reading.contacts[0] = BagContact { body: forearm, point: fist + Vec3::new(0.0, 0.0, 0.04), impulse: Vec3::Z };
        reading.contacts[1] =
            BagContact { body: forearm, point: fist + Vec3::new(0.0, 0.2, 0.0), impulse: 2.0 * Vec3::Z };
        reading.contacts[2] = BagContact { body: Body::Torso.index(), point: Vec3::ZERO, impulse: 4.0 * Vec3::Z };
        reading.contact_count = 3;
        let features = sensor.features(&reading);
        assert_eq!(features[feature_index("fist_r_impulse_z").expect("feature")], 1.0);
        assert_eq!(features[feature_index("fist_l_impulse_z").expect("feature")], 0.0);
        assert_eq!(features[feature_index("character_impulse_z").expect("feature")], 7.0);
    }

    #[test]
    fn a_hit_is_not_a_velocity_jump() {
        let mut sensor = Sensor::new(rest_geometry());
        let flags_index = feature_index("exploit_flags").expect("feature");
        let mut reading = reading_at_rest();
        reading.bodies[Body::ForearmR.index()].linear_velocity = Vec3::new(0.0, 0.0, 11.0);
        sensor.features(&reading);
        reading.bodies[Body::ForearmR.index()].linear_velocity = Vec3::ZERO;
        let fist = Sensor::new(rest_geometry()).fists(&reading)[0].0;
        reading.contacts[0] =
            BagContact { body: Body::ForearmR.index(), point: fist, impulse: Vec3::new(0.0, 0.0, 15.0) };
        reading.contact_count = 1;
        assert_eq!(sensor.features(&reading)[flags_index] as u32 & guard::VELOCITY_JUMP, 0);
    }
}
