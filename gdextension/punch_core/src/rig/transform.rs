//! Checks on the transforms a game hands over (a model's, a skeleton's, a bone's, a character's, a target's):
//! a game may scale a node to 0 (a spawn that pops in), mirror it (scale.x = -1), stretch it, make it huge, or an
//! animation or a broken import may put a NaN in it. glam's conversions assert on such input in debug builds
//! (`Quat::from_mat3` wants normalized axes), so every rotation read from the engine goes through here first, and
//! the caller gets a typed reason instead of a panic.

use glam::{Mat3, Quat, Vec3, Vec4};

/// What is wrong with a transform (a basis, an origin or a rotation) read from the engine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, thiserror::Error)]
pub enum TransformError {
    /// A NaN or an infinity in it (a broken import, an animation or a computation gone wrong), or a scale so
    /// large that its size overflows.
    #[error("is not a number (NaN or infinite)")]
    NotFinite,
    /// No size along one axis or more (a scale of 0), or axes that lie in one plane.
    #[error("has no size (a scale of 0)")]
    NoSize,
    /// A negative scale on one axis (or three): its left and right are swapped.
    #[error("is mirrored (a negative scale)")]
    Mirrored,
    /// A rotation (quaternion) of length 0: not a rotation at all.
    #[error("is a rotation of length 0")]
    ZeroRotation,
}

impl TransformError {
    /// A short word for the cause, to key "said once" sets and name it in messages.
    pub fn key(self) -> &'static str {
        match self {
            TransformError::NotFinite => "NaN",
            TransformError::NoSize => "scale 0",
            TransformError::Mirrored => "mirrored",
            TransformError::ZeroRotation => "zero rotation",
        }
    }
}

/// Axes closer than this to one plane (the determinant of the normalized axes) count as having no size.
const FLAT_AXES: f32 = 1e-6;

/// The rotation of a basis given by its columns, scaled uniformly or not: the axes normalized and made
/// orthogonal (Gram-Schmidt from X, then Y). A basis with a NaN, with no size on an axis (or flat), or mirrored
/// is refused with the reason. A basis that passes also has a determinant that is finite and not 0, so its
/// inverse exists.
pub fn rotation_of(columns: [Vec3; 3]) -> Result<Quat, TransformError> {
    if !columns.iter().all(|c| c.is_finite()) {
        return Err(TransformError::NotFinite);
    }
    let determinant = columns[0].dot(columns[1].cross(columns[2]));
    if !determinant.is_finite() {
        return Err(TransformError::NotFinite);
    }
    // Below the smallest normal f32 (0 included) its inverse overflows: no size that f32 can undo.
    if determinant.abs() < f32::MIN_POSITIVE {
        return Err(TransformError::NoSize);
    }
    // Scaled by the largest component first, so a huge or tiny axis normalizes without overflow or underflow.
    let unit = |c: Vec3| -> Result<Vec3, TransformError> {
        let largest = c.abs().max_element();
        if largest == 0.0 {
            return Err(TransformError::NoSize);
        }
        (c / largest).try_normalize().ok_or(TransformError::NoSize)
    };
    let [x, y, z] = [unit(columns[0])?, unit(columns[1])?, unit(columns[2])?];
    let handedness = x.dot(y.cross(z));
    if handedness.abs() < FLAT_AXES {
        return Err(TransformError::NoSize);
    }
    if handedness < 0.0 {
        return Err(TransformError::Mirrored);
    }
    let y = (y - y.dot(x) * x).try_normalize().ok_or(TransformError::NoSize)?;
    let z = x.cross(y);
    Ok(Quat::from_mat3(&Mat3::from_cols(x, y, z)).normalize())
}

/// A placement (a basis's columns and an origin) as a rotation and a position, checked as `rotation_of` does,
/// with the origin finite too.
pub fn placement_of(columns: [Vec3; 3], origin: Vec3) -> Result<(Quat, Vec3), TransformError> {
    if !origin.is_finite() {
        return Err(TransformError::NotFinite);
    }
    Ok((rotation_of(columns)?, origin))
}

/// A quaternion read from the engine (x, y, z, w), normalized; refused when it has a NaN or a length of 0.
pub fn unit_quat(x: f32, y: f32, z: f32, w: f32) -> Result<Quat, TransformError> {
    let v = Vec4::new(x, y, z, w);
    if !v.is_finite() {
        return Err(TransformError::NotFinite);
    }
    let largest = v.abs().max_element();
    if largest == 0.0 {
        return Err(TransformError::ZeroRotation);
    }
    (v / largest).try_normalize().map(Quat::from_vec4).ok_or(TransformError::ZeroRotation)
}

/// Causes already reported by one node, so that each is said once and not every frame.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SaidOnce {
    said: Vec<(String, TransformError)>,
}

impl SaidOnce {
    /// True the first time `cause` is met for `subject` (a bone's or a node's name): say it then, not after.
    pub fn first(&mut self, subject: &str, cause: TransformError) -> bool {
        if self.said.iter().any(|(s, c)| s == subject && *c == cause) {
            return false;
        }
        self.said.push((subject.to_string(), cause));
        true
    }

    /// Forgets what was said (a new skeleton or map: its problems are news again).
    pub fn clear(&mut self) {
        self.said.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn columns(rotation: Quat, scale: Vec3) -> [Vec3; 3] {
        let m = Mat3::from_quat(rotation) * Mat3::from_diagonal(scale);
        [m.x_axis, m.y_axis, m.z_axis]
    }

    #[test]
    fn a_scaled_basis_keeps_its_rotation_however_it_is_scaled() {
        let q = Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3);
        for scale in [
            Vec3::ONE,
            Vec3::splat(0.01),
            Vec3::new(0.01, 0.02, 0.01),
            Vec3::new(1.0, 0.01, 3.0),
            Vec3::splat(1e6),
            Vec3::splat(1e-8),
        ] {
            let r = rotation_of(columns(q, scale)).expect("a rotation");
            assert!(r.angle_between(q) < 1e-3, "{scale}: {}", r.angle_between(q));
            assert!(r.is_normalized());
        }
    }

    #[test]
    fn zero_negative_and_nan_scales_are_refused_with_their_cause() {
        let q = Quat::from_rotation_z(1.1);
        assert_eq!(rotation_of(columns(q, Vec3::ZERO)), Err(TransformError::NoSize));
        assert_eq!(rotation_of(columns(q, Vec3::new(1.0, 0.0, 1.0))), Err(TransformError::NoSize));
        // So small that its determinant is below f32's normal numbers: its inverse overflows, so no size either.
        assert_eq!(rotation_of(columns(q, Vec3::splat(1e-15))), Err(TransformError::NoSize));
        assert_eq!(rotation_of(columns(q, Vec3::new(-1.0, 1.0, 1.0))), Err(TransformError::Mirrored));
        assert_eq!(rotation_of(columns(q, Vec3::splat(-1.0))), Err(TransformError::Mirrored));
        assert_eq!(rotation_of(columns(q, Vec3::new(1.0, -1.0, -1.0))).map(|_| ()), Ok(()), "a half turn, no mirror");
        assert_eq!(rotation_of(columns(q, Vec3::new(f32::NAN, 1.0, 1.0))), Err(TransformError::NotFinite));
        assert_eq!(rotation_of(columns(q, Vec3::splat(f32::INFINITY))), Err(TransformError::NotFinite));
        assert_eq!(rotation_of(columns(q, Vec3::splat(1e20))), Err(TransformError::NotFinite), "its size overflows");
        // Axes in one plane (a sheared basis squashed flat) have no size either.
        assert_eq!(rotation_of([Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)]), Err(TransformError::NoSize));
        assert_eq!(placement_of(columns(q, Vec3::ONE), Vec3::new(0.0, f32::NAN, 0.0)), Err(TransformError::NotFinite));
    }

    #[test]
    fn quaternions_from_the_engine_are_normalized_or_refused() {
        let q = unit_quat(0.0, 2.0, 0.0, 0.0).expect("valid");
        assert!(q.is_normalized() && (q * Vec3::X - -Vec3::X).length() < 1e-6);
        assert!(unit_quat(1e-30, 0.0, 0.0, 1e-30).expect("tiny but a direction").is_normalized());
        assert_eq!(unit_quat(0.0, 0.0, 0.0, 0.0), Err(TransformError::ZeroRotation));
        assert_eq!(unit_quat(f32::NAN, 0.0, 0.0, 1.0), Err(TransformError::NotFinite));
    }

    #[test]
    fn each_cause_is_said_once_per_subject() {
        let mut said = SaidOnce::default();
        assert!(said.first("skeleton", TransformError::NoSize));
        assert!(!said.first("skeleton", TransformError::NoSize));
        assert!(said.first("skeleton", TransformError::Mirrored));
        assert!(said.first("Hips", TransformError::NoSize));
        said.clear();
        assert!(said.first("skeleton", TransformError::NoSize));
    }
}
