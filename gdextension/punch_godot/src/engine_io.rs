//! Between the engine and the core: reading bodies and contacts into the core's types, and driving the joint
//! motors from its commands. Shared by the training world (physics-server bodies) and by
//! `PunchCharacter`/`PunchController` in a game (scene nodes).

use glam::{Quat, Vec3};
use godot::builtin::{Basis, Rid, Transform3D, Vector3};
use godot::classes::physics_server_3d::{G6dofJointAxisFlag, G6dofJointAxisParam};
use godot::classes::{
    Marker3D, Node3D, PhysicsDirectBodyState3D, PhysicsDirectSpaceState3D, PhysicsServer3D,
    PhysicsShapeQueryParameters3D,
};
use godot::obj::{Gd, Singleton};
use punch_core::contract::character::{
    Axis, BODY_COUNT, Body, EngineAxis, JOINTS, engine_axis, joint_dofs, neck_engine_axis,
};
use punch_core::contract::sensing::{BagContact, CharacterGeometry, FrameReading, MAX_BAG_CONTACTS};
use punch_core::game::punch::Touch;

use crate::convert::{godot_axis, rotation, vec3};

/// One joint axis's engine settings, for scene-node joints (`PunchCharacter`) and physics-server joints (the
/// training world) alike, so that both build the same constraint: linear axes locked, the DOF table's angular
/// limits and motor torque (`engine_axis`) or the neck's range and spring (`neck_engine_axis`), motors at rest.
pub struct AxisSettings {
    pub params: [(G6dofJointAxisParam, f32); 9],
    pub flags: [(G6dofJointAxisFlag, bool); 6],
}

/// The settings of `axis` of joint `joint_index` (`JOINTS` order).
pub fn joint_axis_settings(joint_index: usize, axis: Axis) -> AxisSettings {
    axis_settings(engine_axis(joint_index, axis))
}

/// The settings of `axis` of the neck.
pub fn neck_axis_settings(axis: Axis) -> AxisSettings {
    axis_settings(neck_engine_axis(axis))
}

fn axis_settings(settings: EngineAxis) -> AxisSettings {
    AxisSettings {
        params: [
            (G6dofJointAxisParam::LINEAR_LOWER_LIMIT, 0.0),
            (G6dofJointAxisParam::LINEAR_UPPER_LIMIT, 0.0),
            (G6dofJointAxisParam::ANGULAR_LOWER_LIMIT, settings.lower_rad),
            (G6dofJointAxisParam::ANGULAR_UPPER_LIMIT, settings.upper_rad),
            (G6dofJointAxisParam::ANGULAR_MOTOR_FORCE_LIMIT, settings.max_torque_nm),
            (G6dofJointAxisParam::ANGULAR_MOTOR_TARGET_VELOCITY, 0.0),
            (G6dofJointAxisParam::ANGULAR_SPRING_STIFFNESS, settings.spring_nm_per_rad),
            (G6dofJointAxisParam::ANGULAR_SPRING_DAMPING, settings.spring_damping_nms_per_rad),
            (G6dofJointAxisParam::ANGULAR_SPRING_EQUILIBRIUM_POINT, 0.0),
        ],
        flags: [
            (G6dofJointAxisFlag::ENABLE_LINEAR_LIMIT, true),
            (G6dofJointAxisFlag::ENABLE_ANGULAR_LIMIT, true),
            (G6dofJointAxisFlag::ENABLE_ANGULAR_SPRING, settings.spring_nm_per_rad > 0.0),
            (G6dofJointAxisFlag::ENABLE_LINEAR_SPRING, false),
            (G6dofJointAxisFlag::ENABLE_LINEAR_MOTOR, false),
            (G6dofJointAxisFlag::ENABLE_MOTOR, settings.motor),
        ],
    }
}

/// Turns the motors of every actuated axis off (`enabled` false: the body hangs in its joints' limits, a knock-down)
/// or back on.
pub fn enable_motors(joint_rids: &[Rid; 5], enabled: bool) {
    let mut server = PhysicsServer3D::singleton();
    for (joint_index, rid) in joint_rids.iter().enumerate() {
        for (_, dof) in joint_dofs(joint_index) {
            server.generic_6dof_joint_set_flag(*rid, godot_axis(dof.axis), G6dofJointAxisFlag::ENABLE_MOTOR, enabled);
        }
    }
}

/// Scales every actuated axis's motor torque limit to `scale` times the DOF table's (1: the table's own).
pub fn scale_motor_torque(joint_rids: &[Rid; 5], scale: f32) {
    let mut server = PhysicsServer3D::singleton();
    for (joint_index, rid) in joint_rids.iter().enumerate() {
        for (_, dof) in joint_dofs(joint_index) {
            let param = G6dofJointAxisParam::ANGULAR_MOTOR_FORCE_LIMIT;
            server.generic_6dof_joint_set_param(*rid, godot_axis(dof.axis), param, dof.max_torque_nm * scale);
        }
    }
}

/// Sets each joint's motor target velocities (Godot's 6DOF convention, `JOINTS` order) on its actuated axes.
pub fn drive_joints(joint_rids: &[Rid; 5], motor_velocities: &[Vec3; 5]) {
    let mut server = PhysicsServer3D::singleton();
    for (joint_index, (rid, velocity)) in joint_rids.iter().zip(motor_velocities).enumerate() {
        for (_, dof) in joint_dofs(joint_index) {
            let value = velocity[dof.axis.index()];
            server.generic_6dof_joint_set_param(
                *rid,
                godot_axis(dof.axis),
                G6dofJointAxisParam::ANGULAR_MOTOR_TARGET_VELOCITY,
                value,
            );
        }
    }
}

/// Adds the contacts the target reported with the character's bodies (`body_rids`, `Body::ALL` order).
pub fn add_bag_contacts(
    target: &Gd<PhysicsDirectBodyState3D>,
    body_rids: &[Rid; BODY_COUNT],
    reading: &mut FrameReading,
) {
    for contact in 0..target.get_contact_count() {
        let collider = target.get_contact_collider(contact);
        let Some(body) = body_rids.iter().position(|rid| *rid == collider) else { continue };
        if reading.contact_count == MAX_BAG_CONTACTS {
            break;
        }
        reading.contacts[reading.contact_count] = BagContact {
            body,
            point: vec3(target.get_contact_local_position(contact)),
            impulse: vec3(target.get_contact_impulse(contact)),
        };
        reading.contact_count += 1;
    }
}

/// The character's rest-pose geometry from the transforms of its bodies (`Body::ALL` order) and joints
/// (`JOINTS` order) in one frame, and of its root in that frame. The fist markers are read from `root`'s
/// scene. Target data (bag size and mass) is left at zero for the caller to fill.
pub fn character_geometry(
    root: &Gd<Node3D>,
    bodies: &[Transform3D; BODY_COUNT],
    joints: &[Transform3D; 5],
    root_transform: Transform3D,
) -> Result<CharacterGeometry, String> {
    let mut fist_offsets = [Vec3::ZERO; 2];
    let mut fist_radius_m = 0.0;
    for (side, path) in ["ForearmR/FistR", "ForearmL/FistL"].into_iter().enumerate() {
        let marker = root
            .get_node_or_null(path)
            .and_then(|n| n.try_cast::<Marker3D>().ok())
            .ok_or_else(|| format!("missing fist marker '{path}'"))?;
        fist_offsets[side] = vec3(marker.get_position());
        fist_radius_m =
            marker.get_meta("radius_m").try_to::<f32>().map_err(|_| format!("'{path}' has no 'radius_m' metadata"))?;
    }
    let joint_anchors = std::array::from_fn(|j| {
        let at = joints[j].origin;
        let local = |body: usize| vec3(bodies[body].affine_inverse() * at);
        (local(JOINTS[j].parent.index()), local(JOINTS[j].child.index()))
    });
    // Read with the scale taken out: a character under a scaled parent (a rig in centimetres) has scaled bodies here.
    let turn = |basis: Basis, what: &str| rotation(basis).map_err(|cause| format!("{what} {cause}"));
    let mut rest_rotations = [Quat::IDENTITY; BODY_COUNT];
    for (i, rest) in rest_rotations.iter_mut().enumerate() {
        *rest = turn(bodies[i].basis, Body::ALL[i].node_name())?;
    }
    Ok(CharacterGeometry {
        rest_rotations,
        fist_offsets,
        fist_radius_m,
        joint_anchors,
        bag_radius_m: 0.0,
        bag_height_m: 0.0,
        bag_mass_kg: 0.0,
        root_rotation: turn(root_transform.basis, "the character")?,
        root_position: vec3(root_transform.origin),
        pelvis_rest_position: vec3(bodies[Body::Pelvis.index()].origin),
    })
}

/// Reads the contacts of the character's forearms (`forearms`: `Body::ALL` index and physics state): those
/// with the target's physics object (`target`) or with anything on `hit_layers` become `touches`, for hit
/// detection. When `target_reports` is false, the forearms' contacts with the target also go into `reading`
/// as the target's contacts (otherwise the caller reads them from the target, as the training server does).
/// Impulses and points are taken on the other body's side. Only the forearms are read: reading all five
/// moving bodies' contact lists made the controller's frame markedly slower (BENCHMARKS.md).
pub fn read_forearm_contacts(
    forearms: &[(usize, Gd<PhysicsDirectBodyState3D>)],
    target: Option<Rid>,
    target_reports: bool,
    hit_layers: u32,
    reading: &mut FrameReading,
    touches: &mut Vec<Touch>,
) {
    let server = PhysicsServer3D::singleton();
    for (body, state) in forearms {
        for contact in 0..state.get_contact_count() {
            let collider = state.get_contact_collider(contact);
            let on_target = Some(collider) == target;
            if !on_target && server.body_get_collision_layer(collider) & hit_layers == 0 {
                continue;
            }
            let point = vec3(state.get_contact_collider_position(contact));
            let impulse = -vec3(state.get_contact_impulse(contact));
            if on_target && !target_reports && reading.contact_count < MAX_BAG_CONTACTS {
                reading.contacts[reading.contact_count] = BagContact { body: *body, point, impulse };
                reading.contact_count += 1;
            }
            let collider = state.get_contact_collider_id(contact);
            touches.push(Touch { body: *body, collider, point, impulse, overlap: false });
        }
    }
}

/// Adds the areas on `mask` that overlap each fist (`fists`: forearm's `Body::ALL` index and fist centre)
/// as touches; `query` is a sphere query of the fist's size, reused frame after frame.
pub fn add_area_touches(
    space: &mut Gd<PhysicsDirectSpaceState3D>,
    query: &mut Gd<PhysicsShapeQueryParameters3D>,
    fists: [(usize, Vec3); 2],
    mask: u32,
    touches: &mut Vec<Touch>,
) {
    query.set_collision_mask(mask);
    for (body, centre) in fists {
        query.set_transform(Transform3D::new(Basis::IDENTITY, Vector3::new(centre.x, centre.y, centre.z)));
        for found in space.intersect_shape(&*query).iter_shared() {
            let Some(collider) = found.get("collider_id").and_then(|id| id.try_to::<i64>().ok()) else { continue };
            touches.push(Touch { body, collider: collider as u64, point: centre, overlap: true, ..Touch::default() });
        }
    }
}
