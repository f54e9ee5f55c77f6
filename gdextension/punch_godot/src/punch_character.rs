//! `PunchCharacter`: the root node of the character scene. It finds its bodies and joints by name,
//! configures the joints from the core's DOF table (limits, motors, torque limits), and reads and drives
//! the bodies for the controller in `punch_core`.

use glam::Vec3;
use godot::classes::generic6_dof_joint_3d::{Flag, Param};
use godot::builtin::{Rid, Vector3Axis};
use godot::classes::physics_server_3d::G6dofJointAxisParam;
use godot::classes::{Generic6DofJoint3D, INode3D, Node3D, PhysicsServer3D, RigidBody3D};
use godot::global::godot_error;
use godot::obj::{Base, Gd, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::character::{Axis, Body, JOINTS, joint_dofs};
use punch_core::sensing::{BodyState, CharacterGeometry};

use crate::convert::{body_state, quat, static_state, vec3};

/// Node names of the fist markers (children of the forearms) and the fists' collision shapes.
const FIST_MARKERS: [(&str, &str); 2] = [("ForearmR/FistR", "ForearmR/FistShape"), ("ForearmL/FistL", "ForearmL/FistShape")];

/// A physics-based upper-body character: pelvis fixed in place, a welded head-neck-chest torso, and two
/// arms with 10 actuated degrees of freedom (waist 2, shoulders 3 each, elbows 1 each), driven by joint
/// motors. Use the `punch_character.tscn` scene of the addon rather than building one by hand.
#[derive(GodotClass)]
#[class(base = Node3D, init)]
pub struct PunchCharacter {
    rig: Option<Rig>,
    base: Base<Node3D>,
}

/// The character's nodes, found once.
pub struct Rig {
    pub pelvis: Gd<Node3D>,
    /// Rigid bodies in `Body::ALL` order without the pelvis.
    pub bodies: [Gd<RigidBody3D>; 5],
    /// The joints' physics-server RIDs: motors are driven through the server every frame, skipping the
    /// node setters' bookkeeping.
    pub joint_rids: [Rid; 5],
    /// Collision-shape index of each fist inside its forearm body (contacts report it).
    pub fist_shape_indices: [i32; 2],
    /// Instance ids of the forearms [right, left] and of every body, to recognise contacts.
    pub forearm_ids: [u64; 2],
    pub body_ids: [u64; 6],
    pub geometry: CharacterGeometry,
}

impl Rig {
    /// All six bodies' states in `Body::ALL` order.
    pub fn read_bodies(&self) -> [BodyState; 6] {
        let mut states = [BodyState::default(); 6];
        states[0] = static_state(&self.pelvis);
        for (state, body) in states[1..].iter_mut().zip(&self.bodies) {
            *state = body_state(body);
        }
        states
    }

    /// Sets each joint's motor target velocities (Godot's 6DOF convention), on actuated axes only.
    pub fn drive(&mut self, motor_velocities: &[Vec3; 5]) {
        let mut server = PhysicsServer3D::singleton();
        for (joint_index, (rid, velocity)) in self.joint_rids.iter().zip(motor_velocities).enumerate() {
            for (_, dof) in joint_dofs(joint_index) {
                let axis = match dof.axis {
                    Axis::X => Vector3Axis::X,
                    Axis::Y => Vector3Axis::Y,
                    Axis::Z => Vector3Axis::Z,
                };
                server.generic_6dof_joint_set_param(*rid, axis, G6dofJointAxisParam::ANGULAR_MOTOR_TARGET_VELOCITY, velocity[dof.axis.index()]);
            }
        }
    }
}

#[godot_api]
impl INode3D for PunchCharacter {
    fn ready(&mut self) {
        if let Err(error) = self.build_rig() {
            godot_error!("PunchCharacter '{}': {error}", self.base().get_name());
        }
    }
}

#[godot_api]
impl PunchCharacter {
    /// True when the character found all its bodies and joints and is ready to be driven.
    #[func]
    fn is_ready_to_punch(&self) -> bool {
        self.rig.is_some()
    }

    /// The rig, once the node is ready.
    pub fn rig(&self) -> Option<&Rig> {
        self.rig.as_ref()
    }

    pub fn rig_mut(&mut self) -> Option<&mut Rig> {
        self.rig.as_mut()
    }

    /// Finds the nodes, records the rest pose, and configures the joints from the DOF table.
    fn build_rig(&mut self) -> Result<(), String> {
        let base = self.base().clone();
        let node = |path: &str| -> Result<Gd<godot::classes::Node>, String> {
            base.get_node_or_null(path).ok_or_else(|| format!("missing node '{path}'"))
        };
        let node3d = |path: &str| node(path)?.try_cast::<Node3D>().map_err(|_| format!("'{path}' is not a Node3D"));
        let rigid = |path: &str| node(path)?.try_cast::<RigidBody3D>().map_err(|_| format!("'{path}' is not a RigidBody3D"));

        let pelvis = node3d(Body::Pelvis.node_name())?;
        let bodies = [Body::Torso, Body::UpperArmR, Body::ForearmR, Body::UpperArmL, Body::ForearmL]
            .map(|body| rigid(body.node_name()));
        let bodies: [Gd<RigidBody3D>; 5] = collect(bodies)?;
        let joints = JOINTS.map(|joint| {
            node(joint.node_name)?.try_cast::<Generic6DofJoint3D>().map_err(|_| format!("'{}' is not a Generic6DOFJoint3D", joint.node_name))
        });
        let mut joints: [Gd<Generic6DofJoint3D>; 5] = collect(joints)?;

        let mut rest_rotations = [glam::Quat::IDENTITY; 6];
        rest_rotations[0] = quat(pelvis.get_global_transform().basis.get_quaternion());
        for (rest, body) in rest_rotations[1..].iter_mut().zip(&bodies) {
            *rest = quat(body.get_global_transform().basis.get_quaternion());
        }
        let body_node = |body: Body| -> Gd<Node3D> {
            if body == Body::Pelvis { pelvis.clone() } else { bodies[body.index() - 1].clone().upcast() }
        };
        let joint_anchors = std::array::from_fn(|j| {
            let anchor = joints[j].get_global_position();
            let local = |body: Body| vec3(body_node(body).get_global_transform().affine_inverse() * anchor);
            (local(JOINTS[j].parent), local(JOINTS[j].child))
        });

        let mut fist_offsets = [Vec3::ZERO; 2];
        let mut fist_shape_indices = [0; 2];
        let mut fist_radius_m = 0.0;
        for (side, (marker_path, shape_path)) in FIST_MARKERS.iter().enumerate() {
            let marker = node3d(marker_path)?;
            fist_offsets[side] = vec3(marker.get_position());
            let shape = node(shape_path)?;
            let forearm = &bodies[[Body::ForearmR, Body::ForearmL][side].index() - 1];
            fist_shape_indices[side] = shape_index(forearm, &shape).ok_or_else(|| format!("'{shape_path}' is not a shape of its forearm"))?;
            fist_radius_m = fist_radius(&shape).unwrap_or(0.045);
        }

        for (joint_index, joint) in joints.iter_mut().enumerate() {
            configure_joint(joint, joint_index);
        }
        // The character's bodies never collide with each other: pushing an arm through the torso would
        // fight the joint motors and pull joints apart.
        for (i, body) in bodies.iter().enumerate() {
            let mut body = body.clone();
            body.add_collision_exception_with(&pelvis.clone().cast::<godot::classes::PhysicsBody3D>());
            for other in &bodies[i + 1..] {
                body.add_collision_exception_with(other);
            }
        }
        let root = self.base().get_global_transform();
        let id = |node: &Gd<Node3D>| node.instance_id().to_i64() as u64;
        let body_ids: [u64; 6] = std::array::from_fn(|i| id(&body_node(Body::ALL[i])));
        let forearm_ids = [body_ids[Body::ForearmR.index()], body_ids[Body::ForearmL.index()]];
        let joint_rids = std::array::from_fn(|j| joints[j].get_rid());
        self.rig = Some(Rig {
            pelvis,
            bodies,
            joint_rids,
            fist_shape_indices,
            forearm_ids,
            body_ids,
            geometry: CharacterGeometry {
                rest_rotations,
                fist_offsets,
                fist_radius_m,
                joint_anchors,
                bag_radius_m: 0.0,
                bag_height_m: 0.0,
                bag_mass_kg: 0.0,
                root_rotation: quat(root.basis.get_quaternion()),
                root_position: vec3(root.origin),
            },
        });
        Ok(())
    }
}

/// Index of a CollisionShape3D among its body's shapes: the index contacts report, which counts shapes,
/// not child nodes.
fn shape_index(body: &Gd<RigidBody3D>, shape_node: &Gd<godot::classes::Node>) -> Option<i32> {
    let mut index = 0;
    for owner in body.get_shape_owners().as_slice() {
        let owner_id = *owner as u32;
        if body.shape_owner_get_owner(owner_id).is_some_and(|node| node.instance_id() == shape_node.instance_id()) {
            return Some(index);
        }
        index += body.shape_owner_get_shape_count(owner_id);
    }
    None
}

/// Radius of a fist's sphere shape.
fn fist_radius(shape_node: &Gd<godot::classes::Node>) -> Option<f32> {
    let shape = shape_node.clone().try_cast::<godot::classes::CollisionShape3D>().ok()?.get_shape()?;
    Some(shape.try_cast::<godot::classes::SphereShape3D>().ok()?.get_radius())
}

/// How far the engine's hard joint limits lie beyond the range actions can target: a joint driven to its
/// target at speed stops on its motor, not by slamming into a hard stop (which pulls joints apart).
const HARD_LIMIT_MARGIN_RAD: f32 = 10.0 * std::f32::consts::PI / 180.0;

/// Limits and motors of one joint from the DOF table. Actuated axes get a velocity motor with the DOF's
/// torque limit and the DOF's range; other axes are locked. Godot's 6DOF angles are mirrored relative to
/// the right-hand rule the core uses, so a range [lo, hi] is set as [-hi, -lo].
pub fn configure_joint(joint: &mut Gd<Generic6DofJoint3D>, joint_index: usize) {
    for axis in [Axis::X, Axis::Y, Axis::Z] {
        let dof = joint_dofs(joint_index).find(|(_, dof)| dof.axis == axis).map(|(_, dof)| dof);
        let margin = HARD_LIMIT_MARGIN_RAD;
        let (lower, upper, torque) = dof.map_or((0.0, 0.0, 0.0), |d| (-d.upper_rad - margin, -d.lower_rad + margin, d.max_torque_nm));
        let params = [
            (Param::ANGULAR_LOWER_LIMIT, lower),
            (Param::ANGULAR_UPPER_LIMIT, upper),
            (Param::ANGULAR_MOTOR_FORCE_LIMIT, torque),
            (Param::ANGULAR_MOTOR_TARGET_VELOCITY, 0.0),
        ];
        let flags = [
            (Flag::ENABLE_ANGULAR_LIMIT, true),
            (Flag::ENABLE_MOTOR, dof.is_some()),
            (Flag::ENABLE_ANGULAR_SPRING, false),
            (Flag::ENABLE_LINEAR_LIMIT, true),
        ];
        // Only changed values are set: a limit change rebuilds the engine's constraint, and scenes whose
        // joints are already configured (the training server's templates) then cost nothing.
        for (param, value) in params {
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
        for (flag, value) in flags {
            let current = match axis {
                Axis::X => joint.get_flag_x(flag),
                Axis::Y => joint.get_flag_y(flag),
                Axis::Z => joint.get_flag_z(flag),
            };
            if current != value {
                match axis {
                    Axis::X => joint.set_flag_x(flag, value),
                    Axis::Y => joint.set_flag_y(flag, value),
                    Axis::Z => joint.set_flag_z(flag, value),
                }
            }
        }
    }
}

/// Configures every joint of a character scene instance that is not in the tree yet.
pub fn configure_joints(character: &Gd<godot::classes::Node>) {
    for (joint_index, joint) in JOINTS.iter().enumerate() {
        if let Some(mut joint) = character.get_node_or_null(joint.node_name).and_then(|n| n.try_cast::<Generic6DofJoint3D>().ok()) {
            configure_joint(&mut joint, joint_index);
        }
    }
}

fn collect<T, const N: usize>(items: [Result<T, String>; N]) -> Result<[T; N], String> {
    let mut out = Vec::with_capacity(N);
    for item in items {
        out.push(item?);
    }
    out.try_into().map_err(|_| "internal: wrong count".to_string())
}
