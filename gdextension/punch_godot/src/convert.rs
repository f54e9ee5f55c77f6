//! Conversions between Godot's math types and glam (the core's).

use glam::{Mat3, Quat, Vec3};
use godot::builtin::{Basis, Quaternion, Vector3, Vector3Axis};
use punch_core::contract::character::Axis;

pub fn vec3(v: Vector3) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

pub fn vector3(v: Vec3) -> Vector3 {
    Vector3::new(v.x, v.y, v.z)
}

pub fn quat(q: Quaternion) -> Quat {
    Quat::from_xyzw(q.x, q.y, q.z, q.w).normalize()
}

pub fn quaternion(q: Quat) -> Quaternion {
    Quaternion::new(q.x, q.y, q.z, q.w)
}

/// The rotation of a basis that may be scaled, however little: a rig imported in centimetres sits under a node
/// scaled by 0.01, whose basis Godot's own `get_quaternion` refuses (its determinant counts as zero).
pub fn rotation(basis: Basis) -> Quat {
    let [a, b, c] = [basis.col_a(), basis.col_b(), basis.col_c()].map(|v| vec3(v).normalize_or_zero());
    Quat::from_mat3(&Mat3::from_cols(a, b, c)).normalize()
}

pub fn godot_axis(axis: Axis) -> Vector3Axis {
    match axis {
        Axis::X => Vector3Axis::X,
        Axis::Y => Vector3Axis::Y,
        Axis::Z => Vector3Axis::Z,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_and_rotations_go_both_ways_and_a_scaled_basis_keeps_its_rotation() {
        let v = Vec3::new(1.0, -2.0, 3.5);
        assert_eq!(vec3(vector3(v)), v);
        let q = Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3);
        assert!(quat(quaternion(q)).angle_between(q) < 1e-5);
        // A rig imported in centimetres: its node's basis is its rotation scaled by 0.01 (by 0.02 along one axis).
        for scale in [Vector3::splat(0.01), Vector3::new(0.01, 0.02, 0.01)] {
            let basis = Basis::from_quaternion(quaternion(q)) * Basis::from_scale(scale);
            assert!(rotation(basis).angle_between(q) < 1e-4, "{scale:?}");
        }
    }
}
