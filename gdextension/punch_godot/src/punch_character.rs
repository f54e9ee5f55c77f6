//! `PunchCharacter`: the root node of the character scene. In a game it makes the scene physically what
//! training used (joints configured from the core's DOF table, no collisions between its own bodies), and it
//! reads and drives its bodies for `PunchController` with the same core code the training server uses.

use glam::Vec3;
use godot::builtin::{Rid, Transform3D, Vector2, Vector3};
use godot::classes::generic6_dof_joint_3d::{Flag, Param};
use godot::classes::{
    Generic6DofJoint3D, INode3D, Node3D, PhysicsBody3D, PhysicsDirectBodyState3D, PhysicsServer3D, RigidBody3D,
};
use godot::global::godot_error;
use godot::obj::{Base, EngineEnum, Gd, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::arm_size::{ARM_SCALE_RANGE, ArmLengths, ArmScale};
use punch_core::character::{Axis, Body, JOINTS};
use punch_core::sensing::{BodyState, CharacterGeometry, MAX_BAG_CONTACTS};

use crate::arm_sizing::{SceneArms, rebuild_joints};
use crate::convert::{quat, vec3, vector3};
use crate::engine_io::{character_geometry, drive_joints, joint_axis_settings};

/// A physics-based upper-body character: pelvis fixed in place, a welded head-neck-chest torso, and two
/// arms with 10 actuated degrees of freedom (waist 2, shoulders 3 each, elbows 1 each), driven by joint
/// motors. Use the addon's `punch_character.tscn` rather than building one by hand; a `PunchController`
/// makes it punch.
#[derive(GodotClass)]
#[class(base = Node3D, init)]
pub struct PunchCharacter {
    rig: Option<Rig>,
    /// The arms as the scene had them, captured at the first `size_arms`.
    scene_arms: Option<SceneArms>,
    base: Base<Node3D>,
}

/// The character's bodies and joints, found at `ready`.
pub struct Rig {
    /// `Body::ALL` order.
    pub bodies: Vec<Gd<PhysicsBody3D>>,
    pub joint_rids: [Rid; 5],
    /// The bodies' physics-server RIDs (`Body::ALL` order), to recognise their contacts on a target.
    pub body_rids: [Rid; 6],
    /// Each body as a `RigidBody3D` when it is one (`Body::ALL` order), cast once here: a cast every frame
    /// was a measurable part of the controller's per-frame work (BENCHMARKS.md, controller inference).
    rigid: [Option<Gd<RigidBody3D>>; 6],
    /// The physics states of the forearms (`Body::ALL` index, state), to read the fists' contacts.
    pub forearm_states: Vec<(usize, Gd<PhysicsDirectBodyState3D>)>,
    /// Rest-pose geometry (without target data, which the controller adds).
    pub geometry: CharacterGeometry,
    /// Each body's rest transform relative to the character's root (`Body::ALL` order).
    rest_from_root: [Transform3D; 6],
    /// The arms' lengths as the bodies and joints are now.
    pub arm_lengths: ArmLengths,
}

impl Rig {
    /// The rest-pose geometry of the character standing at `root` (its global transform now): where it was
    /// built does not matter, so a character moved or turned since `ready` senses in its own frame.
    pub fn geometry_at(&self, root: Transform3D) -> CharacterGeometry {
        let mut geometry = self.geometry;
        geometry.rest_rotations = std::array::from_fn(|i| quat((root * self.rest_from_root[i]).basis.get_quaternion()));
        geometry.root_rotation = quat(root.basis.get_quaternion());
        geometry.root_position = vec3(root.origin);
        geometry
    }

    /// World state of every body, `Body::ALL` order. The nodes are read rather than the physics-server
    /// states: a node moved by the game (`reset_pose`, a character placed elsewhere) reads its new place at
    /// once, its physics state only after the next physics step.
    pub fn read_bodies(&self) -> [BodyState; 6] {
        std::array::from_fn(|i| {
            let transform = self.bodies[i].get_global_transform();
            let (linear, angular) = match &self.rigid[i] {
                Some(rigid) => (vec3(rigid.get_linear_velocity()), vec3(rigid.get_angular_velocity())),
                None => (Vec3::ZERO, Vec3::ZERO),
            };
            BodyState {
                position: vec3(transform.origin),
                rotation: quat(transform.basis.get_quaternion()),
                linear_velocity: linear,
                angular_velocity: angular,
            }
        })
    }

    /// Sets the joint motors (Godot's 6DOF convention) on actuated axes.
    pub fn drive(&self, motor_velocities: &[Vec3; 5]) {
        drive_joints(&self.joint_rids, motor_velocities);
    }
}

#[godot_api]
impl INode3D for PunchCharacter {
    fn ready(&mut self) {
        match self.set_up() {
            Ok(rig) => self.rig = Some(rig),
            Err(error) => godot_error!("PunchCharacter '{}': {error}", self.base().get_name()),
        }
    }
}

#[godot_api]
impl PunchCharacter {
    /// True when the character found all its bodies and joints and configured them.
    #[func]
    fn is_ready_to_punch(&self) -> bool {
        self.rig.is_some()
    }

    /// Puts every body back in its rest (guard) pose where the character now stands, with no velocity: a
    /// fresh start for the next punch. Joint motors are set to rest as well.
    #[func]
    fn reset_pose(&mut self) {
        let Some(rig) = self.rig.as_ref() else {
            godot_error!("PunchCharacter '{}': reset_pose() before the character is ready", self.base().get_name());
            return;
        };
        let root = self.base().get_global_transform();
        for (body, rest) in rig.bodies.iter().zip(&rig.rest_from_root) {
            let mut body = body.clone();
            body.set_global_transform(root * *rest);
            if let Ok(mut rigid) = body.try_cast::<RigidBody3D>() {
                rigid.set_linear_velocity(Vector3::ZERO);
                rigid.set_angular_velocity(Vector3::ZERO);
            }
        }
        rig.drive(&[Vec3::ZERO; 5]);
    }

    /// Writes the limits and motors of the core's DOF table into this character's joint nodes, before it is
    /// in a scene tree. The scene builder calls it so the saved scene holds them: each joint is then created
    /// once, in scene order, as in the training server, instead of being rebuilt at `ready` (a rebuild moves
    /// the constraint in Jolt's solve order). Returns false, with an error, if a joint is missing.
    #[func]
    fn store_joint_settings(&mut self) -> bool {
        let base = self.base().clone();
        for (joint_index, joint) in JOINTS.iter().enumerate() {
            match base.get_node_or_null(joint.node_name).and_then(|n| n.try_cast::<Generic6DofJoint3D>().ok()) {
                Some(mut node) => configure_joint(&mut node, joint_index),
                None => {
                    godot_error!("PunchCharacter: missing Generic6DOFJoint3D '{}'", joint.node_name);
                    return false;
                }
            }
        }
        true
    }

    /// Sizes the simulated arms to a character's: `upper_arm_m` from shoulder joint to elbow joint, `forearm_m`
    /// from elbow joint to the fist's centre, `shoulder_width_m` between the two shoulder joints. The bodies,
    /// shapes, fists and joints move (masses stay; inertia follows the length), always from the scene's own
    /// proportions (upper arm 0.282 m, forearm 0.337 m, shoulders 0.36 m apart), and the character is reset to
    /// its guard. The arm (shoulder to fist) must be 0.75 to 1.25 times the scene's and each length 0.65 to 1.35
    /// times; outside that, or before the character is ready, one error says why, the arms keep their size and
    /// this returns false. Call it between punches: `PunchSkeletonModifier` does, with `size_to_rig` on.
    #[func]
    fn size_arms(&mut self, upper_arm_m: f32, forearm_m: f32, shoulder_width_m: f32) -> bool {
        let wanted = ArmLengths { upper_arm_m, forearm_m, shoulder_width_m };
        match self.try_size_arms(wanted) {
            Ok(()) => true,
            Err(error) => {
                godot_error!("PunchCharacter '{}': cannot size the arms: {error}", self.base().get_name());
                false
            }
        }
    }

    /// The simulated arms' lengths now: (upper arm, elbow to fist centre, shoulder width), m.
    #[func]
    fn arm_lengths(&self) -> Vector3 {
        let lengths = self.rig.as_ref().map(|rig| rig.arm_lengths).unwrap_or(ArmLengths {
            upper_arm_m: 0.0,
            forearm_m: 0.0,
            shoulder_width_m: 0.0,
        });
        Vector3::new(lengths.upper_arm_m, lengths.forearm_m, lengths.shoulder_width_m)
    }

    /// The arm lengths' accepted range for `size_arms` (shoulder to fist centre), as fractions of the scene's.
    #[func]
    fn arm_scale_range() -> Vector2 {
        Vector2::new(ARM_SCALE_RANGE.0, ARM_SCALE_RANGE.1)
    }

    fn try_size_arms(&mut self, wanted: ArmLengths) -> Result<(), String> {
        let rig = self.rig.as_ref().ok_or("the character is not ready")?;
        if self.scene_arms.is_none() {
            let root = self.base().clone().upcast::<Node3D>();
            self.scene_arms = Some(SceneArms::capture(&root, &rig.bodies, &rig.rest_from_root, &rig.geometry)?);
        }
        let scene = self.scene_arms.as_ref().ok_or("no scene arms")?;
        let scale = ArmScale::between(scene.lengths, wanted).map_err(|e| e.to_string())?;
        let root = self.base().get_global_transform();
        // The torso and pelvis back at rest too: the joints are rebuilt from the bodies' places.
        for i in [Body::Pelvis.index(), Body::Torso.index()] {
            let mut body = rig.bodies[i].clone();
            body.set_global_transform(root * rig.rest_from_root[i]);
            if let Ok(mut rigid) = body.try_cast::<RigidBody3D>() {
                rigid.set_linear_velocity(Vector3::ZERO);
                rigid.set_angular_velocity(Vector3::ZERO);
            }
        }
        scene.apply(root, scale);
        rebuild_joints(&self.base().clone().upcast::<Node3D>())?;
        self.rig = Some(self.set_up()?);
        if let Some(rig) = self.rig.as_ref() {
            rig.drive(&[Vec3::ZERO; 5]);
        }
        Ok(())
    }

    pub fn rig(&self) -> Option<&Rig> {
        self.rig.as_ref()
    }

    fn set_up(&mut self) -> Result<Rig, String> {
        let base = self.base().clone();
        let bodies: Vec<Gd<PhysicsBody3D>> = Body::ALL
            .iter()
            .map(|body| {
                base.get_node_or_null(body.node_name())
                    .and_then(|n| n.try_cast::<PhysicsBody3D>().ok())
                    .ok_or_else(|| format!("missing physics body '{}'", body.node_name()))
            })
            .collect::<Result<_, _>>()?;
        let mut joints = Vec::new();
        for (joint_index, joint) in JOINTS.iter().enumerate() {
            let mut node = base
                .get_node_or_null(joint.node_name)
                .and_then(|n| n.try_cast::<Generic6DofJoint3D>().ok())
                .ok_or_else(|| format!("missing Generic6DOFJoint3D '{}'", joint.node_name))?;
            configure_joint(&mut node, joint_index);
            joints.push(node);
        }
        let mut server = PhysicsServer3D::singleton();
        let mut forearm_states = Vec::new();
        for (i, body) in bodies.iter().enumerate() {
            for other in &bodies[i + 1..] {
                body.clone().add_collision_exception_with(other);
            }
            if let Ok(mut rigid) = body.clone().try_cast::<RigidBody3D>() {
                // The controller reads hits from the character's own contacts, whatever the target reports.
                let reported = rigid.get_max_contacts_reported().max(MAX_BAG_CONTACTS as i32);
                rigid.set_max_contacts_reported(reported);
                if [Body::ForearmR, Body::ForearmL].contains(&Body::ALL[i]) {
                    let state = server
                        .body_get_direct_state(rigid.get_rid())
                        .ok_or_else(|| format!("body '{}' has no physics state", rigid.get_name()))?;
                    forearm_states.push((i, state));
                }
            }
        }
        let body_transforms: [Transform3D; 6] = std::array::from_fn(|i| bodies[i].get_global_transform());
        let joint_transforms: [Transform3D; 5] = std::array::from_fn(|j| joints[j].get_global_transform());
        let root_inverse = base.get_global_transform().affine_inverse();
        let geometry = character_geometry(&base, &body_transforms, &joint_transforms, base.get_global_transform())?;
        let at = |j: usize| vec3(joint_transforms[j].origin);
        let fist = vec3(body_transforms[Body::ForearmR.index()] * vector3(geometry.fist_offsets[0]));
        let arm_lengths = ArmLengths {
            upper_arm_m: at(2).distance(at(1)),
            forearm_m: fist.distance(at(2)),
            shoulder_width_m: at(1).distance(at(3)),
        };
        Ok(Rig {
            arm_lengths,
            rigid: std::array::from_fn(|i| bodies[i].clone().try_cast::<RigidBody3D>().ok()),
            joint_rids: std::array::from_fn(|j| joints[j].get_rid()),
            body_rids: std::array::from_fn(|i| bodies[i].get_rid()),
            forearm_states,
            geometry,
            rest_from_root: std::array::from_fn(|i| root_inverse * body_transforms[i]),
            bodies,
        })
    }
}

/// Limits and motors of one joint node (`joint_axis_settings`, the same as the training world's joints). Only
/// changed values are set: a limit change rebuilds the engine's constraint, which moves it in Jolt's solve
/// order. The addon's scene already holds these values (`store_joint_settings`), so at `ready` this changes
/// nothing; it matters only for a hand-edited scene. The node's enums have the physics server's values.
fn configure_joint(joint: &mut Gd<Generic6DofJoint3D>, joint_index: usize) {
    for axis in Axis::ALL {
        let settings = joint_axis_settings(joint_index, axis);
        for (param, value) in settings.params {
            let param = Param::from_ord(param.ord());
            let current = match axis {
                Axis::X => joint.get_param_x(param),
                Axis::Y => joint.get_param_y(param),
                Axis::Z => joint.get_param_z(param),
            };
            if current != value {
                match axis {
                    Axis::X => joint.set_param_x(param, value),
                    Axis::Y => joint.set_param_y(param, value),
                    Axis::Z => joint.set_param_z(param, value),
                }
            }
        }
        for (flag, enabled) in settings.flags {
            let flag = Flag::from_ord(flag.ord());
            let current = match axis {
                Axis::X => joint.get_flag_x(flag),
                Axis::Y => joint.get_flag_y(flag),
                Axis::Z => joint.get_flag_z(flag),
            };
            if current != enabled {
                match axis {
                    Axis::X => joint.set_flag_x(flag, enabled),
                    Axis::Y => joint.set_flag_y(flag, enabled),
                    Axis::Z => joint.set_flag_z(flag, enabled),
                }
            }
        }
    }
}
