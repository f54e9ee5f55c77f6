//! Conversions between Godot's math types and glam (the core's), and reading body state from nodes.

use glam::{Quat, Vec3};
use godot::builtin::{Quaternion, Vector3};
use godot::classes::{Node3D, RigidBody3D};
use godot::obj::Gd;
use punch_core::sensing::BodyState;

pub fn vec3(v: Vector3) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

pub fn quat(q: Quaternion) -> Quat {
    Quat::from_xyzw(q.x, q.y, q.z, q.w).normalize()
}

/// Position and rotation of a node; zero velocities (static bodies, markers).
pub fn static_state(node: &Gd<Node3D>) -> BodyState {
    let transform = node.get_global_transform();
    BodyState {
        position: vec3(transform.origin),
        rotation: quat(transform.basis.get_quaternion()),
        linear_velocity: Vec3::ZERO,
        angular_velocity: Vec3::ZERO,
    }
}

/// Full state of a rigid body (position of its origin, which the scenes put at the centre of mass).
pub fn body_state(body: &Gd<RigidBody3D>) -> BodyState {
    let transform = body.get_global_transform();
    BodyState {
        position: vec3(transform.origin),
        rotation: quat(transform.basis.get_quaternion()),
        linear_velocity: vec3(body.get_linear_velocity()),
        angular_velocity: vec3(body.get_angular_velocity()),
    }
}
