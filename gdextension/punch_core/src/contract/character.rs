//! The punching character's control spec: bodies, joints, the 10 actuated degrees of freedom, how an action
//! becomes joint targets, and the motor law that drives the joints toward them.
//!
//! Frame: the character faces +Z (toward the bag), +X is the character's left, +Y is up (right-handed).
//! Joint frames are aligned with that frame in the rest pose (a boxing guard), so every joint angle is 0 at
//! rest, and an angle is the component of the rotation vector of the child relative to the parent, about the
//! joint's X, Y or Z axis (right-hand rule).
//!
//! Drive: each joint is a Jolt 6DOF constraint whose angular *velocity motors* have a torque limit. Every
//! physics frame the motor target is `gain * (rotation vector from current to target)`, capped at
//! `MAX_JOINT_SPEED_RAD_S`. Jolt solves motors inside its constraint solver, so this is stable for any action
//! sequence (unlike explicit PD torques on light segments), and the torque limits keep speeds human.

use glam::{Quat, Vec3};

/// Physics rate of training and play, in Hz. 120 rather than 60: a forearm spinning at 20 rad/s turns
/// 0.33 rad per 60 Hz step, and Jolt's joints then drift by centimetres; at 120 Hz (with 8 position
/// iterations, see godot_project/project.godot) they stay within millimetres. 50 frames last 0.42 s.
pub const PHYSICS_HZ: u32 = 120;
/// Physics frames each action is held for (the paper's 5).
pub const DEFAULT_DECISION_PERIOD: u32 = 5;
/// Number of actuated degrees of freedom (the action size).
pub const DOF_COUNT: usize = 10;
/// Motor law gain, 1/s: a joint closes its error with a 1/gain = 50 ms time constant when torque allows.
pub const POSITION_GAIN_PER_S: f32 = 20.0;
/// Cap on commanded joint speed, rad/s. Fast human elbow extension in punches approaches 25 rad/s; 18 keeps
/// peak fist speeds near the human maximum (about 12 m/s) under any action sequence.
pub const MAX_JOINT_SPEED_RAD_S: f32 = 18.0;

/// Number of rigid bodies of the character (`Body::ALL`).
pub const BODY_COUNT: usize = 7;

/// Rigid bodies of the character, in the order every per-body array uses. The pelvis is kinematic: it carries the root.
/// The head (with the neck) comes last: it hangs on the passive `NECK` joint and no policy drives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Body {
    Pelvis,
    Torso,
    UpperArmR,
    ForearmR,
    UpperArmL,
    ForearmL,
    Head,
}

impl Body {
    pub const ALL: [Body; BODY_COUNT] =
        [Body::Pelvis, Body::Torso, Body::UpperArmR, Body::ForearmR, Body::UpperArmL, Body::ForearmL, Body::Head];

    /// Node name of the body in the character scene.
    pub const fn node_name(self) -> &'static str {
        match self {
            Body::Pelvis => "Pelvis",
            Body::Torso => "Torso",
            Body::UpperArmR => "UpperArmR",
            Body::ForearmR => "ForearmR",
            Body::UpperArmL => "UpperArmL",
            Body::ForearmL => "ForearmL",
            Body::Head => "Head",
        }
    }

    pub const fn index(self) -> usize {
        self as usize
    }

    /// The part of the body a hit on this body strikes, as `PunchCharacter.hit_taken` names it: the pelvis and
    /// the chest are the torso.
    pub const fn part(self) -> BodyPart {
        match self {
            Body::Head => BodyPart::Head,
            Body::Pelvis | Body::Torso => BodyPart::Torso,
            Body::UpperArmR | Body::ForearmR => BodyPart::RightArm,
            Body::UpperArmL | Body::ForearmL => BodyPart::LeftArm,
        }
    }
}

/// A part of the body a hit strikes (`PunchCharacter.take_hit`, `hit_taken`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodyPart {
    Head,
    Torso,
    LeftArm,
    RightArm,
}

impl BodyPart {
    pub const ALL: [BodyPart; 4] = [BodyPart::Head, BodyPart::Torso, BodyPart::LeftArm, BodyPart::RightArm];

    /// Its name in signals and calls.
    pub const fn name(self) -> &'static str {
        match self {
            BodyPart::Head => "head",
            BodyPart::Torso => "torso",
            BodyPart::LeftArm => "left_arm",
            BodyPart::RightArm => "right_arm",
        }
    }

    /// The part named `name`, if it is one.
    pub fn named(name: &str) -> Option<BodyPart> {
        BodyPart::ALL.into_iter().find(|part| part.name() == name)
    }

    /// The bodies a hit on this part may push (the one nearest the hit takes it).
    pub const fn bodies(self) -> &'static [Body] {
        match self {
            BodyPart::Head => &[Body::Head],
            BodyPart::Torso => &[Body::Torso],
            BodyPart::LeftArm => &[Body::UpperArmL, Body::ForearmL],
            BodyPart::RightArm => &[Body::UpperArmR, Body::ForearmR],
        }
    }

    /// An arm: a punch whose fist struck one first was blocked.
    pub const fn is_arm(self) -> bool {
        matches!(self, BodyPart::LeftArm | BodyPart::RightArm)
    }
}

/// A joint axis in the joint frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    pub const fn index(self) -> usize {
        self as usize
    }

    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];
}

/// One joint: a Generic6DOFJoint3D node between a parent and a child body.
#[derive(Debug, Clone, Copy)]
pub struct JointSpec {
    pub node_name: &'static str,
    pub parent: Body,
    pub child: Body,
}

/// The joints, in the order every per-joint array uses.
pub const JOINTS: [JointSpec; 5] = [
    JointSpec { node_name: "Waist", parent: Body::Pelvis, child: Body::Torso },
    JointSpec { node_name: "ShoulderR", parent: Body::Torso, child: Body::UpperArmR },
    JointSpec { node_name: "ElbowR", parent: Body::UpperArmR, child: Body::ForearmR },
    JointSpec { node_name: "ShoulderL", parent: Body::Torso, child: Body::UpperArmL },
    JointSpec { node_name: "ElbowL", parent: Body::UpperArmL, child: Body::ForearmL },
];

/// The neck: the head hangs on it from the chest, held by springs and never driven (no policy observes or moves
/// it), so a hit on the head snaps it and it swings back. Not one of `JOINTS`: it is created after them, in the
/// game as in the training server.
pub const NECK: JointSpec = JointSpec { node_name: "Neck", parent: Body::Torso, child: Body::Head };

/// How far the neck turns either way from upright about each axis (X: nodding, Y: turning, Z: tilting), rad:
/// inside an adult's active range (about 50° of flexion and 60° of extension, 70° of rotation, 45° of tilt).
pub const NECK_RANGE_RAD: [f32; 3] = [deg(40.0), deg(60.0), deg(35.0)];
/// The neck's springs about X, Y and Z, N m/rad: a head (5.55 kg, its centre 0.12 m above the neck joint) nods
/// about 6.6 Hz, and leans about 1.6° behind the chest when the trunk nods at 50 rad/s² (a punch's); softer to the
/// side, where the trunk does not give (the waist does not bend sideways): 30 N s on the forehead from the front or
/// the side moves the head at least 5 cm.
pub const NECK_STIFFNESS_NM_PER_RAD: [f32; 3] = [200.0, 120.0, 100.0];
/// The neck's damping about X, Y and Z, N m s/rad: about 0.7 of critical, so a snapped head settles within a swing.
pub const NECK_DAMPING_NMS_PER_RAD: [f32; 3] = [6.7, 2.3, 4.8];

/// One actuated degree of freedom: a joint axis with limits relative to the rest (guard) pose and a torque
/// limit for its motor.
#[derive(Debug, Clone, Copy)]
pub struct DofSpec {
    pub name: &'static str,
    /// Index into `JOINTS`.
    pub joint: usize,
    pub axis: Axis,
    pub lower_rad: f32,
    pub upper_rad: f32,
    pub max_torque_nm: f32,
    /// What a positive angle does, for the env card.
    pub positive: &'static str,
}

const fn deg(value: f32) -> f32 {
    value * std::f32::consts::PI / 180.0
}

/// The 10 actuated DOF, in action order. Limits are human ranges of motion expressed relative to the guard
/// pose (upper arm 35 degrees forward, elbow bent 120 degrees); torques approximate adult male strength.
pub const DOFS: [DofSpec; DOF_COUNT] = [
    DofSpec {
        name: "waist_flexion",
        joint: 0,
        axis: Axis::X,
        lower_rad: deg(-15.0),
        upper_rad: deg(30.0),
        max_torque_nm: 150.0,
        positive: "trunk leans forward",
    },
    DofSpec {
        name: "waist_rotation",
        joint: 0,
        axis: Axis::Y,
        lower_rad: deg(-45.0),
        upper_rad: deg(45.0),
        max_torque_nm: 100.0,
        positive: "trunk turns left",
    },
    DofSpec {
        name: "shoulder_r_flexion",
        joint: 1,
        axis: Axis::X,
        lower_rad: deg(-120.0),
        upper_rad: deg(90.0),
        max_torque_nm: 70.0,
        positive: "right arm swings back",
    },
    DofSpec {
        name: "shoulder_r_rotation",
        joint: 1,
        axis: Axis::Y,
        lower_rad: deg(-60.0),
        upper_rad: deg(80.0),
        max_torque_nm: 50.0,
        positive: "right arm turns left (across the body)",
    },
    DofSpec {
        name: "shoulder_r_abduction",
        joint: 1,
        axis: Axis::Z,
        lower_rad: deg(-110.0),
        upper_rad: deg(30.0),
        max_torque_nm: 60.0,
        positive: "right arm moves in toward the body",
    },
    DofSpec {
        name: "elbow_r_extension",
        joint: 2,
        axis: Axis::X,
        lower_rad: deg(-25.0),
        upper_rad: deg(118.0),
        max_torque_nm: 60.0,
        positive: "right elbow straightens",
    },
    DofSpec {
        name: "shoulder_l_flexion",
        joint: 3,
        axis: Axis::X,
        lower_rad: deg(-120.0),
        upper_rad: deg(90.0),
        max_torque_nm: 70.0,
        positive: "left arm swings back",
    },
    DofSpec {
        name: "shoulder_l_rotation",
        joint: 3,
        axis: Axis::Y,
        lower_rad: deg(-80.0),
        upper_rad: deg(60.0),
        max_torque_nm: 50.0,
        positive: "left arm turns left (away from the body)",
    },
    DofSpec {
        name: "shoulder_l_abduction",
        joint: 3,
        axis: Axis::Z,
        lower_rad: deg(-30.0),
        upper_rad: deg(110.0),
        max_torque_nm: 60.0,
        positive: "left arm moves out, away from the body",
    },
    DofSpec {
        name: "elbow_l_extension",
        joint: 4,
        axis: Axis::X,
        lower_rad: deg(-25.0),
        upper_rad: deg(118.0),
        max_torque_nm: 60.0,
        positive: "left elbow straightens",
    },
];

/// Which axes of a joint are actuated (the others are locked by the constraint).
pub fn joint_dofs(joint: usize) -> impl Iterator<Item = (usize, &'static DofSpec)> {
    DOFS.iter().enumerate().filter(move |(_, dof)| dof.joint == joint)
}

/// How much harder than the DOF table's torques a block's guard holds (`PunchController.block()`): a braced arm
/// resists with more than it moves with (a muscle's isometric and eccentric strength exceed its concentric), and
/// physical-animation tools raise a body's drive strength for a state the same way.
pub const BRACE_TORQUE_SCALE: f32 = 2.0;

/// How far the engine's hard joint limits lie beyond the range actions can target: a joint driven to its
/// target at speed stops on its motor, not by slamming into a hard stop (which pulls joints apart).
pub const HARD_LIMIT_MARGIN_RAD: f32 = deg(10.0);

/// How the engine must set up one axis of a joint, in Godot's Generic6DOFJoint3D convention, whose angles
/// are mirrored relative to the right-hand rule used here (a range [lo, hi] becomes [-hi, -lo]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EngineAxis {
    pub lower_rad: f32,
    pub upper_rad: f32,
    pub max_torque_nm: f32,
    /// Actuated axes have a velocity motor; the others are locked (lower == upper == 0), but the neck's.
    pub motor: bool,
    /// A spring toward the rest angle (the neck's), N m/rad; 0: none.
    pub spring_nm_per_rad: f32,
    /// The spring's damping, N m s/rad.
    pub spring_damping_nms_per_rad: f32,
}

/// Engine settings of `axis` of joint `joint` (index into `JOINTS`).
pub fn engine_axis(joint: usize, axis: Axis) -> EngineAxis {
    match joint_dofs(joint).find(|(_, dof)| dof.axis == axis) {
        Some((_, dof)) => EngineAxis {
            lower_rad: -dof.upper_rad - HARD_LIMIT_MARGIN_RAD,
            upper_rad: -dof.lower_rad + HARD_LIMIT_MARGIN_RAD,
            max_torque_nm: dof.max_torque_nm,
            motor: true,
            ..EngineAxis::LOCKED
        },
        None => EngineAxis::LOCKED,
    }
}

/// Engine settings of `axis` of the `NECK`: a spring within its range, no motor.
pub fn neck_engine_axis(axis: Axis) -> EngineAxis {
    let range = NECK_RANGE_RAD[axis.index()];
    EngineAxis {
        lower_rad: -range,
        upper_rad: range,
        spring_nm_per_rad: NECK_STIFFNESS_NM_PER_RAD[axis.index()],
        spring_damping_nms_per_rad: NECK_DAMPING_NMS_PER_RAD[axis.index()],
        ..EngineAxis::LOCKED
    }
}

impl EngineAxis {
    /// An axis that does not turn.
    pub const LOCKED: EngineAxis = EngineAxis {
        lower_rad: 0.0,
        upper_rad: 0.0,
        max_torque_nm: 0.0,
        motor: false,
        spring_nm_per_rad: 0.0,
        spring_damping_nms_per_rad: 0.0,
    };
}

/// Joint-angle targets (rad) for an action in [-1, 1]^10: 0 holds the guard pose, +1 and -1 reach the
/// upper and lower limits, linearly on each side. Values outside [-1, 1] are clamped. Returns None when
/// the action has the wrong length or a non-finite value.
pub fn targets_from_action(action: &[f32]) -> Option<[f32; DOF_COUNT]> {
    if action.len() != DOF_COUNT || action.iter().any(|a| !a.is_finite()) {
        return None;
    }
    let mut targets = [0.0; DOF_COUNT];
    for ((target, &a), dof) in targets.iter_mut().zip(action).zip(&DOFS) {
        let a = a.clamp(-1.0, 1.0);
        *target = if a >= 0.0 { a * dof.upper_rad } else { -a * dof.lower_rad };
    }
    Some(targets)
}

/// The action that holds these joint targets (rad): `targets_from_action`'s inverse, each target clamped into its
/// joint's range. A lead-in of it puts a character in that pose before an episode (a stance's guard).
pub fn action_from_targets(targets: &[f32; DOF_COUNT]) -> [f32; DOF_COUNT] {
    std::array::from_fn(|i| {
        let (target, dof) = (targets[i], &DOFS[i]);
        if target >= 0.0 { (target / dof.upper_rad).min(1.0) } else { (-target / dof.lower_rad).max(-1.0) }
    })
}

/// Orientation of the child joint frame relative to the parent joint frame. `parent_rotation` and
/// `child_rotation` are the bodies' world rotations now; `*_rest_rotation` their world rotations in the
/// rest pose (where both joint frames are world-aligned).
pub fn joint_rotation(
    parent_rotation: Quat,
    parent_rest_rotation: Quat,
    child_rotation: Quat,
    child_rest_rotation: Quat,
) -> Quat {
    let parent_frame = parent_rotation * parent_rest_rotation.inverse();
    let child_frame = child_rotation * child_rest_rotation.inverse();
    (parent_frame.inverse() * child_frame).normalize()
}

/// Rotation vector (axis * angle, rad) of a unit quaternion, with the angle in [0, pi].
pub fn rotation_vector(rotation: Quat) -> Vec3 {
    let rotation = if rotation.w < 0.0 { -rotation } else { rotation };
    let sin_half = Vec3::new(rotation.x, rotation.y, rotation.z).length();
    if sin_half < 1e-7 {
        return 2.0 * Vec3::new(rotation.x, rotation.y, rotation.z);
    }
    let angle = 2.0 * sin_half.atan2(rotation.w);
    Vec3::new(rotation.x, rotation.y, rotation.z) * (angle / sin_half)
}

/// Target orientation of a joint (child frame relative to parent frame) from the DOF targets.
pub fn joint_target(joint: usize, targets: &[f32; DOF_COUNT]) -> Quat {
    let mut vector = Vec3::ZERO;
    for (index, dof) in joint_dofs(joint) {
        vector[dof.axis.index()] = targets[index];
    }
    Quat::from_scaled_axis(vector)
}

/// Motor target velocities (rad/s, in Godot's 6DOF motor convention) that drive `joint_rotation` toward
/// `target`: the desired relative angular velocity of the child, expressed in the child's joint frame, is
/// gain * rotation vector of the remaining rotation, capped; Godot's 6DOF motor turns the child at *minus*
/// its target velocity (measured under Jolt; tests/python/test_world.py checks every DOF reaches its
/// target), hence the sign.
pub fn motor_velocities(joint_rotation: Quat, target: Quat) -> Vec3 {
    let remaining = joint_rotation.inverse() * target;
    let desired = (POSITION_GAIN_PER_S * rotation_vector(remaining)).clamp_length_max(MAX_JOINT_SPEED_RAD_S);
    -desired
}

/// The DOF angles (rad) of every joint, from joint rotations in `JOINTS` order.
pub fn dof_angles(joint_rotations: &[Quat; 5]) -> [f32; DOF_COUNT] {
    let vectors = joint_rotations.map(rotation_vector);
    std::array::from_fn(|i| vectors[DOFS[i].joint][DOFS[i].axis.index()])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_body_is_a_part_whose_bodies_hold_it_and_every_part_is_named_once() {
        for body in Body::ALL.into_iter().filter(|b| *b != Body::Pelvis) {
            assert!(body.part().bodies().contains(&body), "{body:?}");
        }
        for part in BodyPart::ALL {
            assert_eq!(BodyPart::named(part.name()), Some(part));
            assert_eq!(
                part.is_arm(),
                part.bodies().iter().all(|b| b.node_name().to_lowercase().contains("arm")),
                "{part:?}"
            );
        }
        assert_eq!(BodyPart::named("tail"), None);
        assert_eq!(Body::Pelvis.part(), BodyPart::Torso);
        assert_eq!(Body::Head.part(), BodyPart::Head);
    }

    #[test]
    fn zero_action_holds_the_guard_pose() {
        assert_eq!(targets_from_action(&[0.0; DOF_COUNT]), Some([0.0; DOF_COUNT]));
    }

    #[test]
    fn extreme_actions_reach_the_limits_and_are_clamped() {
        let upper = targets_from_action(&[1.0; DOF_COUNT]).expect("valid");
        let lower = targets_from_action(&[-3.0; DOF_COUNT]).expect("valid");
        for (i, dof) in DOFS.iter().enumerate() {
            assert_eq!(upper[i], dof.upper_rad);
            assert_eq!(lower[i], dof.lower_rad);
            assert!(dof.lower_rad < 0.0 && dof.upper_rad > 0.0, "{} must contain the guard pose", dof.name);
        }
    }

    #[test]
    fn bad_actions_are_refused() {
        assert_eq!(targets_from_action(&[0.0; 9]), None);
        let mut action = [0.0; DOF_COUNT];
        action[3] = f32::NAN;
        assert_eq!(targets_from_action(&action), None);
    }

    #[test]
    fn rotation_vector_inverts_from_scaled_axis() {
        for vector in [Vec3::new(0.3, -0.2, 0.1), Vec3::new(0.0, 2.5, 0.0), Vec3::new(-1.0, 0.4, 1.2), Vec3::ZERO] {
            let back = rotation_vector(Quat::from_scaled_axis(vector));
            assert!((back - vector).length() < 1e-5, "{vector} -> {back}");
        }
    }

    #[test]
    fn joint_rotation_is_identity_at_rest_whatever_the_body_rotations() {
        let parent = Quat::from_rotation_y(0.7);
        let child = Quat::from_rotation_x(-2.7);
        let q = joint_rotation(parent, parent, child, child);
        assert!(rotation_vector(q).length() < 1e-6);
    }

    #[test]
    fn motor_drives_toward_the_target_and_stops_there() {
        let targets = targets_from_action(&[0.5; DOF_COUNT]).expect("valid");
        for joint in 0..JOINTS.len() {
            let target = joint_target(joint, &targets);
            // At the target: no motion commanded.
            assert!(motor_velocities(target, target).length() < 1e-5);
            // Integrate the commanded relative velocity (child frame; motor sign undone) from rest.
            let mut rotation = Quat::IDENTITY;
            for _ in 0..120 {
                let child_frame_velocity = -motor_velocities(rotation, target);
                rotation = (rotation * Quat::from_scaled_axis(child_frame_velocity / PHYSICS_HZ as f32)).normalize();
            }
            assert!(rotation_vector(rotation.inverse() * target).length() < 1e-3, "joint {joint} did not converge");
        }
    }

    #[test]
    fn engine_limits_are_mirrored_and_wider_than_the_action_range() {
        let elbow = engine_axis(2, Axis::X);
        assert!(elbow.motor);
        assert!((elbow.lower_rad - (-deg(118.0) - HARD_LIMIT_MARGIN_RAD)).abs() < 1e-6);
        assert!((elbow.upper_rad - (deg(25.0) + HARD_LIMIT_MARGIN_RAD)).abs() < 1e-6);
        assert_eq!(engine_axis(2, Axis::Y), EngineAxis::LOCKED);
    }

    #[test]
    fn the_neck_is_a_spring_within_its_range_and_no_motor() {
        for axis in Axis::ALL {
            let neck = neck_engine_axis(axis);
            assert!(!neck.motor && neck.max_torque_nm == 0.0, "{axis:?}");
            assert!(neck.lower_rad < 0.0 && neck.upper_rad == -neck.lower_rad, "{axis:?}");
            assert!(neck.spring_nm_per_rad > 0.0 && neck.spring_damping_nms_per_rad > 0.0, "{axis:?}");
        }
        assert!(JOINTS.iter().all(|joint| joint.child != Body::Head), "no policy drives the head");
        assert_eq!((NECK.parent, NECK.child), (Body::Torso, Body::Head));
    }

    #[test]
    fn commanded_speed_is_capped() {
        let far = Quat::from_rotation_x(3.0);
        assert!((motor_velocities(Quat::IDENTITY, far).length() - MAX_JOINT_SPEED_RAD_S).abs() < 1e-4);
    }

    #[test]
    fn an_action_from_targets_gives_those_targets_back() {
        let targets: [f32; DOF_COUNT] = std::array::from_fn(|i| 0.3 * (DOFS[i].lower_rad + DOFS[i].upper_rad));
        let back = targets_from_action(&action_from_targets(&targets)).expect("an action");
        for (a, b) in targets.iter().zip(&back) {
            assert!((a - b).abs() < 1e-6, "{a} against {b}");
        }
        assert_eq!(action_from_targets(&[10.0; DOF_COUNT]), [1.0; DOF_COUNT]);
        assert_eq!(action_from_targets(&[-10.0; DOF_COUNT]), [-1.0; DOF_COUNT]);
    }

    #[test]
    fn dof_angles_read_back_targets() {
        let targets = targets_from_action(&[0.3, -0.2, 0.4, -0.1, 0.2, 0.6, -0.5, 0.1, 0.3, -0.4]).expect("valid");
        let rotations: [Quat; 5] = std::array::from_fn(|joint| joint_target(joint, &targets));
        let angles = dof_angles(&rotations);
        for i in 0..DOF_COUNT {
            assert!((angles[i] - targets[i]).abs() < 1e-5, "{}", DOFS[i].name);
        }
    }
}
