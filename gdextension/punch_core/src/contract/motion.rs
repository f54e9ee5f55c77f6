//! How a character's root moves while it punches, in training: walking in any horizontal direction, turning,
//! a step-in lunge and the vertical bob of walking. In a game the root moves however the game moves it; in
//! training the session moves each slot's kinematic pelvis along one of these, so a policy learns to punch
//! while its body is carried. Positions and velocities are in the character's frame at the punch's start
//! (+Z ahead, +X to its left, +Y up); turning is about +Y (positive: to the character's left, seen from above).

use glam::{Quat, Vec3};
use serde_json::{Value, json};

/// How long a lunge takes, s: a boxer's step-in lands with the punch.
pub const LUNGE_DURATION_S: f32 = 0.25;
/// The bob's frequency, Hz: two steps a second, a brisk walk's cadence.
pub const BOB_HZ: f32 = 2.0;
/// Largest walking speed a motion may ask for, m/s (training draws up to 1.4).
pub const MAX_WALK_MPS: f32 = 3.0;
/// Largest turning rate a motion may ask for, rad/s (training draws up to 120°/s).
pub const MAX_TURN_RAD_S: f32 = 4.0;
/// Largest lunge, m.
pub const MAX_LUNGE_M: f32 = 0.6;
/// Largest bob amplitude, m.
pub const MAX_BOB_M: f32 = 0.1;

/// A root motion: constant walking velocity and turning rate, plus an optional lunge and bob.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyMotion {
    /// Walking velocity toward the character's left (+X of its frame as it turns), m/s.
    pub side_mps: f32,
    /// Walking velocity ahead (+Z of its frame as it turns), m/s.
    pub forward_mps: f32,
    /// Turning rate about +Y, rad/s.
    pub turn_rad_s: f32,
    /// A forward step of this length over `LUNGE_DURATION_S` from the start (minimum jerk), m.
    pub lunge_m: f32,
    /// Vertical bob amplitude (a sine at `BOB_HZ`, starting at 0), m.
    pub bob_m: f32,
}

/// Where the root is and how it moves at one instant, in the frame of the root at the start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RootPose {
    pub position: Vec3,
    pub rotation: Quat,
    pub linear_velocity: Vec3,
    pub angular_velocity: Vec3,
}

impl RootPose {
    /// The root standing still where it started.
    pub const START: Self = Self {
        position: Vec3::ZERO,
        rotation: Quat::IDENTITY,
        linear_velocity: Vec3::ZERO,
        angular_velocity: Vec3::ZERO,
    };

    /// The velocity of a point carried rigidly with the root (at `point`, same frame).
    pub fn velocity_at(&self, point: Vec3) -> Vec3 {
        self.linear_velocity + self.angular_velocity.cross(point - self.position)
    }
}

/// Names of the fields as the protocol writes them, with their largest magnitude.
pub const FIELDS: [(&str, f32); 5] = [
    ("body_side_mps", MAX_WALK_MPS),
    ("body_forward_mps", MAX_WALK_MPS),
    ("body_turn_rad_s", MAX_TURN_RAD_S),
    ("body_lunge_m", MAX_LUNGE_M),
    ("body_bob_m", MAX_BOB_M),
];

impl BodyMotion {
    /// Whether the root stands still (the session then never moves the pelvis, as before motions existed).
    pub fn is_still(&self) -> bool {
        *self == Self::default()
    }

    /// Sets a field by its protocol name; false for a name that is not one.
    pub fn set(&mut self, name: &str, value: f32) -> bool {
        let field = match name {
            "body_side_mps" => &mut self.side_mps,
            "body_forward_mps" => &mut self.forward_mps,
            "body_turn_rad_s" => &mut self.turn_rad_s,
            "body_lunge_m" => &mut self.lunge_m,
            "body_bob_m" => &mut self.bob_m,
            _ => return false,
        };
        *field = value;
        true
    }

    /// As the protocol writes it (fields of a `reset`'s bag placement).
    pub fn to_json_fields(&self) -> [(&'static str, Value); 5] {
        [
            ("body_side_mps", json!(self.side_mps)),
            ("body_forward_mps", json!(self.forward_mps)),
            ("body_turn_rad_s", json!(self.turn_rad_s)),
            ("body_lunge_m", json!(self.lunge_m)),
            ("body_bob_m", json!(self.bob_m)),
        ]
    }

    /// The root at `time_s` after the start (closed form: walking at a constant velocity in a frame that
    /// turns at a constant rate traces a circle).
    pub fn pose_at(&self, time_s: f32) -> RootPose {
        let t = time_s.max(0.0);
        let w = self.turn_rad_s;
        let heading = w * t;
        let rotation = Quat::from_rotation_y(heading);
        // ∫ rotation(w s) ds over [0, t] applied to the walking velocity (x: side, z: forward).
        let (sin_integral, cos_integral) = if w.abs() < 1e-6 {
            (t * t * w / 2.0, t) // ∫ sin(ws) ds ≈ w t²/2, ∫ cos(ws) ds ≈ t
        } else {
            ((1.0 - heading.cos()) / w, heading.sin() / w)
        };
        let (vx, vz) = (self.side_mps, self.forward_mps);
        let mut position =
            Vec3::new(vx * cos_integral + vz * sin_integral, 0.0, -vx * sin_integral + vz * cos_integral);
        let mut linear_velocity = rotation * Vec3::new(vx, 0.0, vz);
        let (lunge_m, lunge_mps) = lunge(self.lunge_m, t);
        position += rotation * Vec3::new(0.0, 0.0, lunge_m);
        // The lunge's step is along the turning heading: its velocity adds the turn's sweep of the offset.
        linear_velocity += rotation * Vec3::new(0.0, 0.0, lunge_mps)
            + Vec3::new(0.0, w, 0.0).cross(rotation * Vec3::new(0.0, 0.0, lunge_m));
        let phase = std::f32::consts::TAU * BOB_HZ * t;
        position.y += self.bob_m * phase.sin();
        linear_velocity.y += self.bob_m * std::f32::consts::TAU * BOB_HZ * phase.cos();
        RootPose { position, rotation, linear_velocity, angular_velocity: Vec3::new(0.0, w, 0.0) }
    }
}

/// A minimum-jerk step of `length_m` over `LUNGE_DURATION_S`: (distance, speed) at `t`.
fn lunge(length_m: f32, t: f32) -> (f32, f32) {
    if length_m == 0.0 {
        return (0.0, 0.0);
    }
    let s = (t / LUNGE_DURATION_S).clamp(0.0, 1.0);
    let distance = length_m * (10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5));
    let speed = length_m * (30.0 * s.powi(2) - 60.0 * s.powi(3) + 30.0 * s.powi(4)) / LUNGE_DURATION_S;
    (distance, speed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The velocities match the positions' derivative (central differences).
    fn assert_consistent(motion: BodyMotion) {
        let h = 1e-3;
        for step in 0..40 {
            let t = 0.01 + step as f32 * 0.0125;
            let (before, now, after) = (motion.pose_at(t - h), motion.pose_at(t), motion.pose_at(t + h));
            let numeric = (after.position - before.position) / (2.0 * h);
            assert!(
                (numeric - now.linear_velocity).length() < 2e-2,
                "{motion:?} at {t}: {numeric} vs {}",
                now.linear_velocity
            );
            let turned = (after.rotation * before.rotation.inverse()).to_scaled_axis() / (2.0 * h);
            assert!((turned - now.angular_velocity).length() < 1e-2);
        }
    }

    #[test]
    fn still_stays_at_the_start() {
        let motion = BodyMotion::default();
        assert!(motion.is_still());
        assert_eq!(motion.pose_at(0.4), RootPose::START);
    }

    #[test]
    fn walking_goes_where_it_faces_and_velocities_match_positions() {
        let forward = BodyMotion { forward_mps: 1.4, ..Default::default() };
        assert!((forward.pose_at(0.5).position - Vec3::new(0.0, 0.0, 0.7)).length() < 1e-6);
        let left = BodyMotion { side_mps: 0.7, ..Default::default() };
        assert!((left.pose_at(1.0).position - Vec3::new(0.7, 0.0, 0.0)).length() < 1e-6);
        for motion in [
            forward,
            left,
            BodyMotion { turn_rad_s: 2.0, ..Default::default() },
            BodyMotion { forward_mps: 1.0, side_mps: -0.5, turn_rad_s: -1.5, ..Default::default() },
            BodyMotion { lunge_m: 0.3, turn_rad_s: 1.0, ..Default::default() },
            BodyMotion { forward_mps: 1.0, bob_m: 0.03, ..Default::default() },
        ] {
            assert_consistent(motion);
        }
    }

    #[test]
    fn turning_while_walking_traces_a_circle() {
        // Walking ahead at v while turning left at w: a circle of radius v/w, centre to the left.
        let motion = BodyMotion { forward_mps: 1.0, turn_rad_s: 1.0, ..Default::default() };
        let half_turn = motion.pose_at(std::f32::consts::PI);
        assert!((half_turn.position - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-4, "{}", half_turn.position);
        assert!((half_turn.linear_velocity - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-4);
    }

    #[test]
    fn a_lunge_steps_its_length_and_stops() {
        let motion = BodyMotion { lunge_m: 0.3, ..Default::default() };
        let done = motion.pose_at(LUNGE_DURATION_S + 0.1);
        assert!((done.position - Vec3::new(0.0, 0.0, 0.3)).length() < 1e-6);
        assert_eq!(done.linear_velocity, Vec3::ZERO);
        assert_eq!(motion.pose_at(0.0).linear_velocity, Vec3::ZERO);
    }

    #[test]
    fn fields_round_trip_by_name() {
        let mut motion = BodyMotion::default();
        for ((name, _), value) in FIELDS.iter().zip([0.1, 0.2, 0.3, 0.4, 0.05]) {
            assert!(motion.set(name, value));
        }
        assert!(!motion.set("body_fly_mps", 1.0));
        let written: Vec<f32> =
            motion.to_json_fields().iter().map(|(_, v)| v.as_f64().expect("number") as f32).collect();
        assert_eq!(written, vec![0.1, 0.2, 0.3, 0.4, 0.05]);
    }
}
