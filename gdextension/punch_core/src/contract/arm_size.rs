//! Sizing the simulated arms to a character: the upper arms, the forearms (elbow to fist centre) and the
//! distance between the shoulders take a game character's lengths, within a documented range of the addon's
//! own proportions (de Leva's adult male: upper arm 0.282 m, elbow to fist centre 0.337 m, shoulder joints
//! 0.36 m apart). `PunchCharacter::size_arms` (punch_godot) applies it to the bodies, shapes and joints.
//!
//! Stretching: each arm segment is stretched along its own line, about its proximal joint, by its length's
//! scale; what lies beyond the segment's far end (the elbow's end of the upper arm, the fist) moves with that
//! end, unstretched, so the fist keeps its size and only the forearm's shaft grows or shrinks (by as much more
//! as puts the fist's centre at the forearm's scaled length: `Stretch::to_reach`). The shoulders move
//! sideways by half the change in their distance. Masses stay (the policies were trained with them); the
//! moments of inertia about the axes across a segment scale with its length squared, as a rod's do.

use glam::Vec3;

/// The arm proportions of a character, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmLengths {
    /// Shoulder joint to elbow joint.
    pub upper_arm_m: f32,
    /// Elbow joint to the fist's centre.
    pub forearm_m: f32,
    /// Between the two shoulder joints.
    pub shoulder_width_m: f32,
}

impl ArmLengths {
    /// Shoulder to fist centre, the arm's length.
    pub fn arm_m(&self) -> f32 {
        self.upper_arm_m + self.forearm_m
    }
}

/// Smallest and largest arm length (shoulder to fist centre) accepted, as a fraction of the character scene's
/// own. 0.75 covers the converted CC0 characters of 1.60 m (their arms are 0.79 of the addon's, MakeHuman's short
/// body having short forearms) and 1.25 a 1.95 m adult's long arms.
pub const ARM_SCALE_RANGE: (f32, f32) = (0.75, 1.25);
/// Smallest and largest length of each segment and of the shoulder distance, as a fraction of the scene's own:
/// wider than the arm's, for rigs whose forearm and upper arm differ from de Leva's ratio.
pub const SEGMENT_SCALE_RANGE: (f32, f32) = (0.65, 1.35);

/// Why a character's arms cannot be sized.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SizeError {
    #[error("{what} of {value_m:.3} m is {scale:.2} times the simulated body's {default_m:.3} m, outside {lo}..{hi}")]
    OutOfRange { what: &'static str, value_m: f32, default_m: f32, scale: f32, lo: f32, hi: f32 },
    #[error("{what} is not a length ({value_m} m)")]
    NotALength { what: &'static str, value_m: f32 },
}

/// How the arms change from the scene's own proportions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmScale {
    pub upper_arm: f32,
    pub forearm: f32,
    /// How far each shoulder moves outward, m (negative: inward).
    pub shoulder_shift_m: f32,
}

/// Names of the fields as the protocol writes them (a reset's placement sizes a training character's arms),
/// with the range each accepts.
pub const FIELDS: [(&str, (f32, f32)); 3] = [
    ("arms_upper_arm_scale", SEGMENT_SCALE_RANGE),
    ("arms_forearm_scale", SEGMENT_SCALE_RANGE),
    ("arms_shoulder_shift_m", (-0.07, 0.07)),
];

impl ArmScale {
    pub const IDENTITY: ArmScale = ArmScale { upper_arm: 1.0, forearm: 1.0, shoulder_shift_m: 0.0 };

    /// Sets a field by its protocol name if the value is in its range; `None` for a name that is not one,
    /// `Some(false)` for a value out of range.
    pub fn set(&mut self, name: &str, value: f32) -> Option<bool> {
        let (_, (lo, hi)) = FIELDS.iter().find(|(field, _)| *field == name)?;
        if !(*lo..=*hi).contains(&value) {
            return Some(false);
        }
        match name {
            "arms_upper_arm_scale" => self.upper_arm = value,
            "arms_forearm_scale" => self.forearm = value,
            _ => self.shoulder_shift_m = value,
        }
        Some(true)
    }

    /// As the protocol writes it, in `FIELDS` order.
    pub fn to_json_fields(&self) -> [(&'static str, serde_json::Value); 3] {
        [
            (FIELDS[0].0, serde_json::json!(self.upper_arm)),
            (FIELDS[1].0, serde_json::json!(self.forearm)),
            (FIELDS[2].0, serde_json::json!(self.shoulder_shift_m)),
        ]
    }

    /// The lengths `default`'s arms get under this scale.
    pub fn lengths(&self, default: ArmLengths) -> ArmLengths {
        ArmLengths {
            upper_arm_m: default.upper_arm_m * self.upper_arm,
            forearm_m: default.forearm_m * self.forearm,
            shoulder_width_m: default.shoulder_width_m + 2.0 * self.shoulder_shift_m,
        }
    }

    /// The scale that turns `default` into `wanted`, if `wanted` is within the documented range.
    pub fn between(default: ArmLengths, wanted: ArmLengths) -> Result<ArmScale, SizeError> {
        let check = |what: &'static str, value_m: f32, default_m: f32, (lo, hi): (f32, f32)| {
            if !(value_m.is_finite() && value_m > 0.0) {
                return Err(SizeError::NotALength { what, value_m });
            }
            let scale = value_m / default_m;
            // A hair of slack: the scene's own lengths are read back from the physics engine in single precision.
            if !((lo - 1e-4)..=(hi + 1e-4)).contains(&scale) {
                return Err(SizeError::OutOfRange { what, value_m, default_m, scale, lo, hi });
            }
            Ok(scale)
        };
        check("the arm (shoulder to fist centre)", wanted.arm_m(), default.arm_m(), ARM_SCALE_RANGE)?;
        let upper_arm = check("the upper arm", wanted.upper_arm_m, default.upper_arm_m, SEGMENT_SCALE_RANGE)?;
        let forearm =
            check("the forearm (elbow to fist centre)", wanted.forearm_m, default.forearm_m, SEGMENT_SCALE_RANGE)?;
        check("the shoulder width", wanted.shoulder_width_m, default.shoulder_width_m, SEGMENT_SCALE_RANGE)?;
        Ok(ArmScale {
            upper_arm,
            forearm,
            shoulder_shift_m: 0.5 * (wanted.shoulder_width_m - default.shoulder_width_m),
        })
    }
}

/// One segment's stretch: along `direction` (unit) from `origin` (its proximal joint), by `scale` up to
/// `stretched_m` from the origin; points beyond move with that end, points behind the origin stay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stretch {
    pub origin: Vec3,
    pub direction: Vec3,
    pub scale: f32,
    pub stretched_m: f32,
}

impl Stretch {
    /// The stretch about `origin` that moves `far` to `scale` times its distance from `origin` while the last
    /// `rigid_m` before `far` (a fist's radius) keeps its length: only the part before it stretches.
    pub fn to_reach(origin: Vec3, far: Vec3, rigid_m: f32, scale: f32) -> Stretch {
        let length_m = origin.distance(far);
        let stretched_m = (length_m - rigid_m).max(1e-3);
        Stretch {
            origin,
            direction: (far - origin).normalize_or_zero(),
            scale: 1.0 + (scale - 1.0) * length_m / stretched_m,
            stretched_m,
        }
    }

    pub fn apply(&self, point: Vec3) -> Vec3 {
        let along = (point - self.origin).dot(self.direction).clamp(0.0, self.stretched_m);
        point + (self.scale - 1.0) * along * self.direction
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scale_is_set_by_its_protocol_names_within_their_ranges() {
        let mut scale = ArmScale::IDENTITY;
        assert_eq!(scale.set("arms_upper_arm_scale", 0.7), Some(true));
        assert_eq!(scale.set("arms_forearm_scale", 1.4), Some(false));
        assert_eq!(scale.set("body_bob_m", 0.01), None);
        assert_eq!(scale.upper_arm, 0.7);
        assert_eq!(scale.forearm, 1.0);
        let default = ArmLengths { upper_arm_m: 0.282, forearm_m: 0.337, shoulder_width_m: 0.36 };
        let sized = ArmScale { shoulder_shift_m: 0.01, ..scale }.lengths(default);
        assert!((sized.upper_arm_m - 0.1974).abs() < 1e-6 && (sized.shoulder_width_m - 0.38).abs() < 1e-6);
    }

    const DEFAULT: ArmLengths = ArmLengths { upper_arm_m: 0.282, forearm_m: 0.337, shoulder_width_m: 0.36 };

    #[test]
    fn the_scene_itself_is_the_identity() {
        assert_eq!(ArmScale::between(DEFAULT, DEFAULT), Ok(ArmScale::IDENTITY));
    }

    #[test]
    fn lengths_within_the_range_scale_each_segment() {
        let wanted = ArmLengths { upper_arm_m: 0.2374, forearm_m: 0.2547, shoulder_width_m: 0.3279 };
        let scale = ArmScale::between(DEFAULT, wanted).expect("within range");
        assert!((scale.upper_arm - 0.2374 / 0.282).abs() < 1e-6);
        assert!((scale.forearm - 0.2547 / 0.337).abs() < 1e-6);
        assert!((scale.shoulder_shift_m - 0.5 * (0.3279 - 0.36)).abs() < 1e-6);
    }

    #[test]
    fn the_range_includes_its_ends() {
        for scale in [ARM_SCALE_RANGE.0, ARM_SCALE_RANGE.1] {
            let wanted = ArmLengths {
                upper_arm_m: DEFAULT.upper_arm_m * scale * 1.00005,
                forearm_m: DEFAULT.forearm_m * scale * 1.00005,
                shoulder_width_m: DEFAULT.shoulder_width_m,
            };
            assert!(ArmScale::between(DEFAULT, wanted).is_ok(), "{scale}");
        }
    }

    #[test]
    fn lengths_outside_the_range_are_refused_by_name() {
        let short = ArmLengths { upper_arm_m: 0.2, forearm_m: 0.24, ..DEFAULT };
        let error = ArmScale::between(DEFAULT, short).expect_err("0.71 of the arm");
        assert!(error.to_string().contains("the arm (shoulder to fist centre)"), "{error}");
        let odd = ArmLengths { upper_arm_m: 0.40, forearm_m: 0.25, ..DEFAULT };
        let error = ArmScale::between(DEFAULT, odd).expect_err("upper arm 1.42");
        assert!(error.to_string().contains("the upper arm of 0.400 m"), "{error}");
        let nan = ArmLengths { shoulder_width_m: f32::NAN, ..DEFAULT };
        assert!(matches!(ArmScale::between(DEFAULT, nan), Err(SizeError::NotALength { .. })));
    }

    #[test]
    fn a_stretch_scales_the_segment_and_carries_what_lies_beyond() {
        let stretch = Stretch { origin: Vec3::new(0.0, 1.0, 0.0), direction: -Vec3::Y, scale: 1.2, stretched_m: 0.3 };
        // Behind the origin: stays. Along the segment: scaled. Beyond its end: moved by the end's shift.
        assert_eq!(stretch.apply(Vec3::new(0.0, 1.1, 0.0)), Vec3::new(0.0, 1.1, 0.0));
        assert!((stretch.apply(Vec3::new(0.05, 0.9, 0.0)) - Vec3::new(0.05, 0.88, 0.0)).length() < 1e-6);
        assert!((stretch.apply(Vec3::new(0.0, 0.6, 0.02)) - Vec3::new(0.0, 0.54, 0.02)).length() < 1e-6);
    }

    #[test]
    fn a_stretch_to_reach_puts_the_far_point_at_the_scaled_distance_and_keeps_the_rigid_end() {
        let (elbow, fist) = (Vec3::new(0.1, 1.2, 0.0), Vec3::new(0.1, 1.2, 0.337));
        for scale in [0.8, 1.0, 1.15] {
            let stretch = Stretch::to_reach(elbow, fist, 0.05, scale);
            assert!((stretch.apply(fist).distance(elbow) - 0.337 * scale).abs() < 1e-5, "{scale}");
            // The fist's surface toward the elbow stays 5 cm from its centre.
            let surface = Vec3::new(0.1, 1.2, 0.287);
            assert!((stretch.apply(fist).distance(stretch.apply(surface)) - 0.05).abs() < 1e-5, "{scale}");
        }
    }
}
