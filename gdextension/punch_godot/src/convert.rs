//! Conversions between Godot's math types and glam (the core's).

use glam::{Quat, Vec3};
use godot::builtin::{Quaternion, Vector3, Vector3Axis};
use punch_core::character::Axis;

pub fn vec3(v: Vector3) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

pub fn vector3(v: Vec3) -> Vector3 {
    Vector3::new(v.x, v.y, v.z)
}

pub fn quat(q: Quaternion) -> Quat {
    Quat::from_xyzw(q.x, q.y, q.z, q.w).normalize()
}

pub fn godot_axis(axis: Axis) -> Vector3Axis {
    match axis {
        Axis::X => Vector3Axis::X,
        Axis::Y => Vector3Axis::Y,
        Axis::Z => Vector3Axis::Z,
    }
}
