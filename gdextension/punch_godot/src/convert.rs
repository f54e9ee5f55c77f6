//! Conversions between Godot's math types and glam (the core's).

use glam::{Quat, Vec3};
use godot::builtin::{Basis, Quaternion, Transform3D, Vector3, Vector3Axis};
use punch_core::contract::character::Axis;
use punch_core::rig::transform::{TransformError, placement_of, rotation_of, unit_quat};

pub fn vec3(v: Vector3) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

pub fn vector3(v: Vec3) -> Vector3 {
    Vector3::new(v.x, v.y, v.z)
}

/// A quaternion from the engine, normalized. One with a NaN or of length 0 comes back as it is (no panic: glam's
/// `normalize` asserts on it in debug builds); callers that must tell check it with `checked_quat`.
pub fn quat(q: Quaternion) -> Quat {
    checked_quat(q).unwrap_or(Quat::from_xyzw(q.x, q.y, q.z, q.w))
}

/// A quaternion from the engine (an animation's bone rotation), normalized, or why it is none. One of a normal
/// length is normalized as the extension always did (glam's `normalize`), bit for bit, so that what training and
/// the game sense does not change; one too short for that, by `unit_quat`'s scaled normalization.
pub fn checked_quat(q: Quaternion) -> Result<Quat, TransformError> {
    let raw = Quat::from_xyzw(q.x, q.y, q.z, q.w);
    if raw.is_finite() && raw.length_squared().is_normal() {
        return Ok(raw.normalize());
    }
    unit_quat(q.x, q.y, q.z, q.w)
}

pub fn quaternion(q: Quat) -> Quaternion {
    Quaternion::new(q.x, q.y, q.z, q.w)
}

/// The rotation of a basis that may be scaled, however little or unevenly: a rig imported in centimetres sits under
/// a node scaled by 0.01, whose basis godot-rust's `get_quaternion` refuses with a panic (its determinant counts as
/// zero). A basis with a NaN, no size (a scale of 0) or mirrored is refused, saying which
/// (`punch_core::rig::transform::rotation_of`); one that passes has an inverse.
pub fn rotation(basis: Basis) -> Result<Quat, TransformError> {
    // A rotation (every physics body's basis, an unscaled node's, read every frame): Godot's own quaternion of it,
    // as the extension always read it, bit for bit, so that training and the game sense exactly what they did (the
    // golden run). Anything else (scaled, NaN, no size, mirrored) takes the checked path, which says why it fails.
    if is_rotation(basis) {
        return Ok(quat(basis.get_quaternion()));
    }
    rotation_of([basis.col_a(), basis.col_b(), basis.col_c()].map(vec3))
}

/// Whether a basis is a rotation within float error: unit columns at right angles, right-handed (so its
/// determinant is 1 and Godot's `get_quaternion` takes it). A NaN fails every comparison, so it is none.
fn is_rotation(basis: Basis) -> bool {
    const TOLERANCE: f32 = 1e-4;
    let [a, b, c] = [basis.col_a(), basis.col_b(), basis.col_c()].map(vec3);
    [a, b, c].iter().all(|v| (v.length_squared() - 1.0).abs() < TOLERANCE)
        && [a.dot(b), b.dot(c), c.dot(a)].iter().all(|d| d.abs() < TOLERANCE)
        && a.cross(b).dot(c) > 0.0
}

/// A transform as a rotation (its scale taken out) and a position, or why it has none (`rotation`, and the origin
/// finite).
pub fn placement(transform: Transform3D) -> Result<(Quat, Vec3), TransformError> {
    placement_of(
        [transform.basis.col_a(), transform.basis.col_b(), transform.basis.col_c()].map(vec3),
        vec3(transform.origin),
    )
}

/// A transform without its scale (its rotation and origin), or why it has none: what a node's placement means to
/// the simulated body, which keeps its own size.
pub fn rigid(transform: Transform3D) -> Result<Transform3D, TransformError> {
    let rotation = rotation(transform.basis)?;
    if !vec3(transform.origin).is_finite() {
        return Err(TransformError::NotFinite);
    }
    Ok(Transform3D::new(Basis::from_quaternion(quaternion(rotation)), transform.origin))
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
            assert!(rotation(basis).expect("a rotation").angle_between(q) < 1e-4, "{scale:?}");
        }
        // Scale 0, mirrored, NaN: refused, with no panic.
        let rotated = Basis::from_quaternion(quaternion(q));
        assert_eq!(rotation(rotated * Basis::from_scale(Vector3::ZERO)), Err(TransformError::NoSize));
        assert_eq!(rotation(rotated * Basis::from_scale(Vector3::new(-1.0, 1.0, 1.0))), Err(TransformError::Mirrored));
        let nan = Transform3D::new(rotated, Vector3::new(f32::NAN, 0.0, 0.0));
        assert_eq!(rigid(nan), Err(TransformError::NotFinite));
        assert_eq!(checked_quat(Quaternion::new(0.0, 0.0, 0.0, 0.0)), Err(TransformError::ZeroRotation));
        let scaled = Transform3D::new(rotated * Basis::from_scale(Vector3::splat(3.0)), Vector3::ONE);
        let unscaled = rigid(scaled).expect("rigid");
        assert!((unscaled.basis.determinant() - 1.0).abs() < 1e-5 && unscaled.origin == Vector3::ONE);
    }
}
