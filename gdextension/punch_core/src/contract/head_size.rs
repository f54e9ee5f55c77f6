//! Sizing the simulated head to a character's: the head moves along its neck so that its crown stands as high above
//! the shoulder joints as the character's does; the skull keeps its size (adult heads differ far less than bodies:
//! docs/hits.md, "An own rig's head"). The addon's own crown stands 0.29 m above its shoulder joints. `PunchCharacter::size_head` (punch_godot) applies it
//! to the body and its neck's mesh; the mass and inertia stay (the neck's springs were tuned with them).

use super::arm_size::SizeError;

/// Lowest and highest crown accepted, as a fraction of the scene's height of it above the shoulder joints: from a
/// neck 4 cm shorter than the scene's to one 11 cm longer.
pub const HEAD_CROWN_SCALE_RANGE: (f32, f32) = (0.85, 1.4);

/// How far the head moves up its neck (m; negative: down) to put its crown `wanted_m` above the shoulder joints when
/// the scene's crown stands `scene_m` above them, if that is within `HEAD_CROWN_SCALE_RANGE`.
pub fn head_shift_m(scene_m: f32, wanted_m: f32) -> Result<f32, SizeError> {
    let what = "the crown's height above the shoulder joints";
    if !(wanted_m.is_finite() && wanted_m > 0.0) {
        return Err(SizeError::NotALength { what, value_m: wanted_m });
    }
    let scale = wanted_m / scene_m;
    let (lo, hi) = HEAD_CROWN_SCALE_RANGE;
    // A hair of slack: the scene's own lengths are read back from the physics engine in single precision.
    if !((lo - 1e-4)..=(hi + 1e-4)).contains(&scale) {
        return Err(SizeError::OutOfRange { what, value_m: wanted_m, default_m: scene_m, scale, lo, hi });
    }
    Ok(wanted_m - scene_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_head_moves_up_or_down_its_neck_by_the_difference() {
        assert!((head_shift_m(0.29, 0.35).expect("in range") - 0.06).abs() < 1e-6);
        assert!((head_shift_m(0.29, 0.26).expect("in range") + 0.03).abs() < 1e-6);
        assert_eq!(head_shift_m(0.29, 0.29).expect("the scene's"), 0.0);
    }

    #[test]
    fn a_crown_outside_the_range_or_not_a_length_is_refused_saying_why() {
        let too_high = head_shift_m(0.29, 0.45).expect_err("too high");
        assert!(matches!(too_high, SizeError::OutOfRange { .. }));
        assert!(too_high.to_string().contains("crown") && too_high.to_string().contains("0.85..1.4"), "{too_high}");
        assert!(matches!(head_shift_m(0.29, 0.2), Err(SizeError::OutOfRange { .. })));
        for bad in [f32::NAN, -0.3, 0.0, f32::INFINITY] {
            assert!(matches!(head_shift_m(0.29, bad), Err(SizeError::NotALength { .. })), "{bad}");
        }
    }
}
