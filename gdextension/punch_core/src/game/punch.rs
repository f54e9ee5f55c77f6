//! One punch of a game character, free of Godot: the per-decision clock, the designer's runtime noise
//! (which decisions get it, from which seed), hit detection, the punch's record and its end.
//!
//! `PunchController` (punch_godot) only moves data across: each physics frame it hands `Punch::sense` the
//! frame just simulated, runs the policy on the observation when one is asked for (batched with other
//! controllers), and hands the mean action to `Punch::act`, whose motor commands it applies. The training
//! server's `Session` drives the same `CharacterController` in lockstep over many slots.

use glam::Vec3;

use crate::contract::character::{Body, DOF_COUNT};
use crate::contract::controller::CharacterController;
use crate::contract::mirror::{mirror_action, mirror_features};
use crate::contract::observation::{OBS_DIM, observation};
use crate::contract::sensing::{
    CharacterGeometry, FEATURE_COUNT, FIST_CONTACT_MARGIN_M, FrameReading, columns, feature_vector,
};
use crate::contract::spec::{NoiseScale, PolicySpec, UNIFORM_NOISE};
use crate::error::{CoreError, CoreResult};
use crate::game::moves::{Hand, Move};
use crate::game::noise::GaussianNoise;

/// Impulse (N s) on the target above which a fist counts as hitting it.
pub const HIT_IMPULSE_NS: f32 = 0.05;

/// The designer's runtime noise: Gaussian noise of `sigma` (action units) added to the policy's mean action
/// on every decision, or on the first `noisy_decisions` of each punch only (when >= 0). Seeded, so the same
/// seed and sigma give the same sequence of punches.
#[derive(Debug, Clone)]
pub struct RuntimeNoise {
    pub sigma: f32,
    pub noisy_decisions: i32,
    rng: GaussianNoise,
}

impl RuntimeNoise {
    pub fn new(seed: u64, sigma: f32, noisy_decisions: i32) -> Self {
        Self { sigma, noisy_decisions, rng: GaussianNoise::new(seed) }
    }

    /// Whether decision `index` of a punch gets noise.
    pub fn is_noisy(&self, decision: u32) -> bool {
        self.sigma > 0.0 && (self.noisy_decisions < 0 || (decision as i64) < self.noisy_decisions as i64)
    }

    /// The action played at decision `index`: the mean plus noise when the decision is noisy, each degree of
    /// freedom's scaled by `scale` (the policy's `punch_noise_scale`). The noise sequence advances only on
    /// noisy decisions, by one sample per degree of freedom whatever its scale.
    pub fn apply(&mut self, decision: u32, mean: &[f32], scale: &NoiseScale) -> Vec<f32> {
        if !self.is_noisy(decision) {
            return mean.to_vec();
        }
        mean.iter().zip(scale).map(|(m, s)| m + self.sigma * s * self.rng.sample()).collect()
    }
}

/// Something a fist touches this frame, as the engine reported it (world coordinates). The game reports
/// every contact of the character's forearms (and area overlaps of its fists) with whatever it may hit;
/// `Punch` keeps those at the fists.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Touch {
    /// Index into `Body::ALL` of the character's body that touches (only the forearms carry fists).
    pub body: usize,
    /// The engine's id of what is touched (a body or an area): a punch hits each one at most once.
    pub collider: u64,
    /// The contact point on what is touched.
    pub point: Vec3,
    /// Impulse applied to what is touched this frame, N s (zero for an area).
    pub impulse: Vec3,
    /// An area overlapping the fist rather than a contact: it is a hit without an impulse.
    pub overlap: bool,
}

/// A fist struck something for the first time in this punch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// What was hit (`Touch::collider`).
    pub collider: u64,
    /// Contact impulse on what was hit in this first frame, N s (world axes; zero for an area).
    pub impulse: Vec3,
    /// The striking fist's peak speed so far in this punch, m/s.
    pub speed_mps: f32,
    /// Where the fist was (world coordinates).
    pub position: Vec3,
    /// The striking hand (the punching one, or the guard hand).
    pub hand: Hand,
}

impl Hit {
    /// Strength of the hit, N s.
    pub fn impulse_ns(&self) -> f32 {
        self.impulse.length()
    }
}

/// What a punch did, when it ends.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PunchSummary {
    /// Physics frames played.
    pub frames: usize,
    /// The punching fist's peak speed, m/s.
    pub peak_fist_speed_mps: f32,
    /// The off (guard) fist's peak speed, m/s: a guard hand that flails shows here, not above.
    pub peak_off_fist_speed_mps: f32,
    /// Things a fist struck (each counted once per punch).
    pub hits: i64,
    /// The largest contact impulse of a fist in one frame, N s.
    pub strongest_hit_ns: f32,
    /// The punch was ended before its last frame (cancelled, or its policy changed).
    pub interrupted: bool,
    /// The hand that punched.
    pub hand: Hand,
    /// The move it was (None: a policy played as it is, not one of the six).
    pub punch_move: Option<Move>,
    /// The engine's id of the first thing the punching fist struck (None: it struck nothing, a whiff); the game
    /// layer tells a landed punch from a blocked one by what that was.
    pub first_struck: Option<u64>,
}

/// A punch frame by frame (kept when asked for): features [frames x F] (the frame before the first decision
/// left out), observations [decisions x OBS_DIM], mean actions and played actions [decisions x A].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PunchRecord {
    pub features: Vec<f32>,
    pub observations: Vec<f32>,
    pub mean_actions: Vec<f32>,
    pub actions: Vec<f32>,
}

/// What a frame asks of the caller after `Punch::sense`.
#[derive(Debug, Clone, PartialEq)]
pub enum Sensed {
    /// No decision this frame: call `act(None, ..)`.
    Hold,
    /// A decision is due: run the policy on this observation and call `act(Some(mean), ..)`.
    Decide(Box<[f32; OBS_DIM]>),
    /// The punch is over (do not call `act`).
    Finished(PunchSummary, Option<PunchRecord>),
}

/// One running punch.
#[derive(Debug, Clone)]
pub struct Punch {
    controller: CharacterController,
    spec: PolicySpec,
    /// How the runtime noise is spread over the degrees of freedom (the policy's; uniform by default).
    noise_scale: NoiseScale,
    frame: u32,
    /// This frame's reading, kept from sensing to acting.
    reading: FrameReading,
    /// What the fists are touching in a contact episode that was counted as a hit.
    in_contact: Vec<u64>,
    /// Everything this punch has hit: a fist touching it again (an Area3D's edge, a sandbag swinging back
    /// into the fist) is not another hit.
    struck: Vec<u64>,
    summary: PunchSummary,
    record: Option<PunchRecord>,
    /// The punching hand. Policies punch with the right; the left plays the policy in the mirrored world: it
    /// senses the mirrored features and its actions are mirrored before they drive the joints, so everything
    /// the punch measures and records (the "right" fist, its speed) is the punching fist's.
    hand: Hand,
}

impl Punch {
    /// A punch of a character with `geometry`, timed and smoothed as `spec` says; with `record`, it keeps
    /// its `PunchRecord`.
    /// Spreads the runtime noise over the degrees of freedom as the punch's policy asks
    /// (`PunchingPolicy::noise_scale`).
    pub fn with_noise_scale(mut self, scale: NoiseScale) -> Self {
        self.noise_scale = scale;
        self
    }

    pub fn new(geometry: CharacterGeometry, spec: PolicySpec, record: bool) -> Self {
        Self {
            controller: CharacterController::new(geometry, spec.smoothing_window as usize),
            spec,
            noise_scale: UNIFORM_NOISE,
            frame: 0,
            reading: FrameReading::default(),
            in_contact: Vec::new(),
            struck: Vec::new(),
            summary: PunchSummary::default(),
            record: record.then(PunchRecord::default),
            hand: Hand::Right,
        }
    }

    /// Punches with `hand` (the right by default; the left plays the policy mirrored).
    pub fn with_hand(mut self, hand: Hand) -> Self {
        self.hand = hand;
        self.summary.hand = hand;
        self
    }

    /// Names the move this punch is (what its events and summary say).
    pub fn with_move(mut self, punch_move: Option<Move>) -> Self {
        self.summary.punch_move = punch_move;
        self
    }

    /// The punching hand.
    pub fn hand(&self) -> Hand {
        self.hand
    }

    /// The move it is, if it is one of the six.
    pub fn punch_move(&self) -> Option<Move> {
        self.summary.punch_move
    }

    /// The rest geometry of the character it drives.
    pub fn geometry(&self) -> &CharacterGeometry {
        self.controller.geometry()
    }

    /// Physics frames played so far.
    pub fn frame(&self) -> u32 {
        self.frame
    }

    /// World positions and velocities of the fists in `reading`: [(position, velocity); right, left].
    pub fn fists(&self, reading: &FrameReading) -> [(Vec3, Vec3); 2] {
        self.controller.fists(reading)
    }

    /// Ends the punch before its last frame: its summary, marked interrupted, and its record so far.
    pub fn interrupt(mut self) -> (PunchSummary, Option<PunchRecord>) {
        self.summary.frames = self.frame as usize;
        self.summary.interrupted = true;
        (self.summary, self.record)
    }

    /// The decision the current frame belongs to.
    pub fn decision(&self) -> u32 {
        self.frame / self.spec.decision_period
    }

    /// First half of a physics frame: reads the frame just simulated and what the character's forearms
    /// touch. Returns the hits it shows (a fist started touching something) and what the caller does next.
    pub fn sense(&mut self, reading: FrameReading, touches: &[Touch]) -> (Vec<Hit>, Sensed) {
        let features = self.controller.features(&reading);
        let features = if self.hand.is_mirrored() { mirror_features(&features) } else { features };
        let hit = self.track_hits(&features, &reading, touches);
        if let Some(record) = self.record.as_mut().filter(|_| self.frame > 0) {
            record.features.extend_from_slice(&features);
        }
        self.reading = reading;
        if self.frame >= self.spec.frames {
            self.summary.frames = self.frame as usize;
            return (hit, Sensed::Finished(self.summary, self.record.take()));
        }
        if !self.frame.is_multiple_of(self.spec.decision_period) {
            return (hit, Sensed::Hold);
        }
        let observation = observation(&features, self.decision(), self.spec.decisions());
        if let Some(record) = self.record.as_mut() {
            record.observations.extend_from_slice(&observation);
        }
        (hit, Sensed::Decide(Box::new(observation)))
    }

    /// Second half of a physics frame: takes the decision's mean action (when `sense` asked for one), adds
    /// `noise`, and returns the joint motor commands for the next physics step. A non-finite or misshapen
    /// mean is an error (the caller ends the punch).
    pub fn act(&mut self, mean: Option<&[f32]>, noise: &mut RuntimeNoise) -> CoreResult<[Vec3; 5]> {
        if let Some(mean) = mean {
            if mean.iter().any(|v| !v.is_finite()) {
                return Err(CoreError::Inference("the policy returned NaN or infinite actions".into()));
            }
            let action = noise.apply(self.decision(), mean, &self.noise_scale);
            if self.hand.is_mirrored() {
                let action: [f32; DOF_COUNT] = action.as_slice().try_into().map_err(|_| {
                    CoreError::Inference(format!("the policy returned {} actions, not {DOF_COUNT}", action.len()))
                })?;
                self.controller.set_action(&mirror_action(&action))?;
            } else {
                self.controller.set_action(&action)?;
            }
            if let Some(record) = self.record.as_mut() {
                record.mean_actions.extend_from_slice(mean);
                record.actions.extend_from_slice(&action);
            }
        }
        let commands = self.controller.motor_commands(&self.reading);
        self.frame += 1;
        Ok(commands)
    }

    /// Hits of this frame: a fist struck something this punch has not hit yet, counted when the contact's
    /// impulse first exceeds `HIT_IMPULSE_NS` (or at once for an area). A contact episode lasts while the fist
    /// keeps touching it (Jolt keeps a contact, at zero impulse, while the fist rests on or rebounds near a
    /// surface); a later episode with the same thing is no new hit, as a game counts one hit per attack.
    fn track_hits(&mut self, features: &[f32; FEATURE_COUNT], reading: &FrameReading, touches: &[Touch]) -> Vec<Hit> {
        let length = |column: usize| feature_vector(features, column).length();
        let speeds = [length(columns::FIST_R_VEL), length(columns::FIST_L_VEL)];
        self.summary.peak_fist_speed_mps = self.summary.peak_fist_speed_mps.max(speeds[0]);
        self.summary.peak_off_fist_speed_mps = self.summary.peak_off_fist_speed_mps.max(speeds[1]);
        let peaks = [self.summary.peak_fist_speed_mps, self.summary.peak_off_fist_speed_mps];

        // The punching fist first, then the off fist (the features are the punching hand's, mirrored for the left).
        let [right, left] = self.controller.fists(reading);
        let (fists, forearms, hands) = match self.hand {
            Hand::Right => ([right, left], [Body::ForearmR, Body::ForearmL], [Hand::Right, Hand::Left]),
            Hand::Left => ([left, right], [Body::ForearmL, Body::ForearmR], [Hand::Left, Hand::Right]),
        };
        let reach = self.controller.geometry().fist_radius_m + FIST_CONTACT_MARGIN_M;
        // Per collider: the impulse of all fist contacts with it, the fist that touched it, area or not.
        let mut touched: Vec<(u64, Vec3, usize, bool)> = Vec::new();
        for touch in touches {
            let Some(side) = forearms.iter().position(|b| b.index() == touch.body) else {
                continue;
            };
            if !touch.overlap && touch.point.distance(fists[side].0) > reach {
                continue;
            }
            match touched.iter_mut().find(|(collider, ..)| *collider == touch.collider) {
                Some(entry) => {
                    entry.1 += touch.impulse;
                    entry.3 |= touch.overlap;
                }
                None => touched.push((touch.collider, touch.impulse, side, touch.overlap)),
            }
        }
        let mut hits = Vec::new();
        let mut in_contact = Vec::new();
        for (collider, impulse, side, overlap) in touched {
            let continuing = self.in_contact.contains(&collider);
            if !continuing && !overlap && impulse.length() <= HIT_IMPULSE_NS {
                continue;
            }
            in_contact.push(collider);
            self.summary.strongest_hit_ns = self.summary.strongest_hit_ns.max(impulse.length());
            if !continuing && !self.struck.contains(&collider) {
                self.struck.push(collider);
                self.summary.hits += 1;
                if side == 0 && self.summary.first_struck.is_none() {
                    self.summary.first_struck = Some(collider);
                }
                hits.push(Hit {
                    collider,
                    impulse,
                    speed_mps: peaks[side],
                    position: fists[side].0,
                    hand: hands[side],
                });
            }
        }
        self.in_contact = in_contact;
        hits
    }
}

/// Bringing a character back to its guard pose under physics (after a punch, or whenever a game asks): the
/// joint motors drive every joint toward its guard angle (the square guard's rest angle, or a stance's) with the
/// same motor law as a punch.
#[derive(Debug, Clone)]
pub struct Recovery {
    controller: CharacterController,
    guard: [f32; DOF_COUNT],
    frame: u32,
    /// Within this angle of the guard (rad) and slower than this (rad/s), every joint, it is there.
    settled: (f32, f32),
    /// It is not there before this frame, and ends at the other even if still moving.
    frames: (u32, u32),
    /// Whether the head must be back on its neck too (`after_hit`).
    neck_too: bool,
}

impl Recovery {
    /// Longest recovery, frames (0.5 s at 120 Hz): it ends then even if the character is still moving.
    pub const MAX_FRAMES: u32 = 60;
    /// A recovery after a hit (`after_hit`): at least 4 frames (33 ms), at most 240 (2 s at 120 Hz).
    pub const AFTER_HIT_FRAMES: (u32, u32) = (4, 240);
    /// Back in guard: every joint within this angle of its rest angle (rad) ...
    pub const SETTLED_ANGLE_RAD: f32 = 0.02;
    /// ... and slower than this (rad/s).
    pub const SETTLED_SPEED_RAD_S: f32 = 0.2;
    /// Near enough to punch from (`ready_to_punch`), unless a move asks otherwise: every joint within this angle of
    /// its guard angle (rad) ...
    pub const READY_ANGLE_RAD: f32 = 0.1;
    /// ... and slower than this many times that angle per second (1 rad/s for 0.1 rad; the settled guard's 0.2 rad/s
    /// for its 0.02 rad).
    pub const READY_SPEED_PER_ANGLE_HZ: f32 = 10.0;
    /// After a hit the head swings on its neck (springs, no motor) after the driven joints are back: it is back
    /// within this angle of where it rests on the chest (rad; under its own weight it sags about 1.5 degrees) ...
    pub const NECK_SETTLED_ANGLE_RAD: f32 = 0.1;
    /// ... and turning slower than this against the chest (rad/s).
    pub const NECK_SETTLED_SPEED_RAD_S: f32 = 1.0;

    /// A recovery to the guard whose joint targets are `guard` (rad, action order; all 0: the square guard).
    pub fn new(geometry: CharacterGeometry, guard: [f32; DOF_COUNT]) -> Self {
        let mut controller = CharacterController::new(geometry, 1);
        controller.set_targets(guard);
        Self {
            controller,
            guard,
            frame: 0,
            settled: (Self::SETTLED_ANGLE_RAD, Self::SETTLED_SPEED_RAD_S),
            frames: (0, Self::MAX_FRAMES),
            neck_too: false,
        }
    }

    /// The way back after a hit: the push shows in the bodies only after the physics step that follows it, so the
    /// body is not back in guard before `AFTER_HIT_FRAMES.0`, and a hard hit may take until `AFTER_HIT_FRAMES.1`.
    /// The head is back too, not only the driven joints: a hit on the head leaves it swinging on its neck after the
    /// arms and the trunk are back.
    pub fn after_hit(mut self) -> Self {
        self.frames = Self::AFTER_HIT_FRAMES;
        self.neck_too = true;
        self
    }

    /// Drives to `guard` from now on instead (a block's guard turning with its opponent); its frames run on.
    pub fn retarget(&mut self, guard: [f32; DOF_COUNT]) {
        self.controller.set_targets(guard);
        self.guard = guard;
    }

    /// Holds the guard for exactly `frames` physics frames, settled or not (a block, whose end the caller decides).
    pub fn holding(mut self, frames: u32) -> Self {
        self.frames = (frames, frames);
        self
    }

    /// Ends near the guard rather than settled in it: every joint within `angle_rad` of its guard angle and slower
    /// than `READY_SPEED_PER_ANGLE_HZ` times that (a return to guard before a punch, `guard_first`, which the
    /// policies land from as they do from the guard itself; `READY_ANGLE_RAD` unless the move asks nearer). A
    /// non-finite or negative angle is the settled guard's.
    pub fn ready_to_punch(mut self, angle_rad: f32) -> Self {
        let angle_rad = if angle_rad.is_finite() && angle_rad >= 0.0 { angle_rad } else { Self::SETTLED_ANGLE_RAD };
        self.settled = (angle_rad, angle_rad * Self::READY_SPEED_PER_ANGLE_HZ);
        self
    }

    /// Motor commands for the next physics step, or None when the character is back in its guard pose (or
    /// the time is up): the caller then stops driving.
    pub fn step(&mut self, reading: &FrameReading) -> Option<[Vec3; 5]> {
        let features = self.controller.features(reading);
        let (angle_rad, speed_rad_s) = self.settled;
        let settled = (0..DOF_COUNT).all(|i| {
            (features[columns::ANGLES + i] - self.guard[i]).abs() < angle_rad
                && features[columns::SPEEDS + i].abs() < speed_rad_s
        });
        let settled = settled && (!self.neck_too || self.neck_settled(reading));
        if (settled && self.frame >= self.frames.0) || self.frame >= self.frames.1 {
            return None;
        }
        self.frame += 1;
        Some(self.controller.motor_commands(reading))
    }

    /// Whether the head rests on the chest as in the rest pose, give or take `NECK_SETTLED_ANGLE_RAD`, and turns
    /// against it slower than `NECK_SETTLED_SPEED_RAD_S`.
    fn neck_settled(&self, reading: &FrameReading) -> bool {
        let rest = &self.controller.geometry().rest_rotations;
        let (torso, head) = (&reading.bodies[Body::Torso.index()], &reading.bodies[Body::Head.index()]);
        let on_chest = torso.rotation.inverse() * head.rotation;
        let at_rest = rest[Body::Torso.index()].inverse() * rest[Body::Head.index()];
        let off_rad = (at_rest.inverse() * on_chest).normalize().angle_between(glam::Quat::IDENTITY);
        off_rad < Self::NECK_SETTLED_ANGLE_RAD
            && (head.angular_velocity - torso.angular_velocity).length() < Self::NECK_SETTLED_SPEED_RAD_S
    }
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use super::*;
    use crate::fake_world::{FAKE_BAG_ID, FakeWorld, rest_geometry};

    impl Recovery {
        /// Whether it is still driving after `frames` steps on the same reading.
        fn holding_back(mut self, reading: &FrameReading, frames: usize) -> bool {
            (0..frames).all(|_| self.step(reading).is_some()) && self.step(reading).is_some()
        }
    }

    /// Plays one punch on a fake world with a policy given as a closure; returns the decisions' frame
    /// indices, the actions played, the hits and the end.
    fn play(
        spec: PolicySpec,
        noise: &mut RuntimeNoise,
        policy: impl FnMut(&[f32; OBS_DIM]) -> Vec<f32>,
        between_frames: impl FnMut(u32, &mut RuntimeNoise),
    ) -> (Vec<u32>, PunchRecord, Vec<Hit>, PunchSummary) {
        play_scaled(spec, UNIFORM_NOISE, noise, policy, between_frames)
    }

    /// `play`, with the runtime noise spread over the degrees of freedom by `scale`.
    fn play_scaled(
        spec: PolicySpec,
        scale: NoiseScale,
        noise: &mut RuntimeNoise,
        mut policy: impl FnMut(&[f32; OBS_DIM]) -> Vec<f32>,
        mut between_frames: impl FnMut(u32, &mut RuntimeNoise),
    ) -> (Vec<u32>, PunchRecord, Vec<Hit>, PunchSummary) {
        let mut world = FakeWorld::new(1);
        let mut punch = Punch::new(rest_geometry(), spec, true).with_noise_scale(scale);
        let (mut decided_at, mut hits) = (Vec::new(), Vec::new());
        loop {
            let (hit, sensed) = punch.sense(world.read_slot(0), &world.touches_slot(0));
            hits.extend(hit);
            let commands = match sensed {
                Sensed::Finished(summary, record) => {
                    return (decided_at, record.expect("recording"), hits, summary);
                }
                Sensed::Hold => punch.act(None, noise),
                Sensed::Decide(observation) => {
                    decided_at.push(punch.frame());
                    let mean = policy(&observation);
                    punch.act(Some(&mean), noise)
                }
            }
            .expect("acts");
            world.drive_slot(0, &commands);
            world.step();
            between_frames(punch.frame(), noise);
        }
    }

    /// `play` with `hand` punching (the record in the punching hand's frame).
    fn play_with_hand(
        hand: Hand,
        spec: PolicySpec,
        noise: &mut RuntimeNoise,
        mut policy: impl FnMut(&[f32; OBS_DIM]) -> Vec<f32>,
    ) -> (Vec<u32>, PunchRecord, Vec<Hit>, PunchSummary) {
        let mut world = FakeWorld::new(1);
        let mut punch = Punch::new(rest_geometry(), spec, true).with_hand(hand);
        let mut hits = Vec::new();
        loop {
            let (hit, sensed) = punch.sense(world.read_slot(0), &world.touches_slot(0));
            hits.extend(hit);
            let commands = match sensed {
                Sensed::Finished(summary, record) => return (Vec::new(), record.expect("recording"), hits, summary),
                Sensed::Hold => punch.act(None, noise),
                Sensed::Decide(observation) => punch.act(Some(&policy(&observation)), noise),
            }
            .expect("acts");
            world.drive_slot(0, &commands);
            world.step();
        }
    }

    fn forward(_: &[f32; OBS_DIM]) -> Vec<f32> {
        vec![0.6; 10]
    }

    #[test]
    fn decisions_come_every_period_and_the_punch_ends_after_its_frames() {
        let spec = PolicySpec::new(5, 50, 3).expect("valid");
        let (decided_at, record, _, summary) = play(spec, &mut RuntimeNoise::new(0, 0.0, -1), forward, |_, _| {});
        assert_eq!(decided_at, (0..50).step_by(5).collect::<Vec<_>>());
        assert_eq!(summary.frames, 50);
        assert_eq!(record.features.len(), 50 * FEATURE_COUNT);
        assert_eq!(record.observations.len(), 10 * OBS_DIM);
        let phases: Vec<f32> = record.observations.chunks(OBS_DIM).map(|o| o[OBS_DIM - 1]).collect();
        assert_eq!(phases, (0..10).map(|d| d as f32 / 10.0).collect::<Vec<_>>());
        assert_eq!(record.actions, record.mean_actions, "sigma 0 adds nothing");
    }

    #[test]
    fn the_fake_punch_hits_the_bag_once_and_reports_it() {
        let spec = PolicySpec::new(5, 50, 1).expect("valid");
        let (_, _, hits, summary) = play(spec, &mut RuntimeNoise::new(0, 0.0, -1), forward, |_, _| {});
        assert_eq!(hits.len(), 1, "the fist stays on the bag: one hit, not one per frame");
        assert_eq!(summary.hits, 1);
        assert!(summary.strongest_hit_ns > HIT_IMPULSE_NS && summary.peak_fist_speed_mps > 0.0);
        assert_eq!(hits[0].speed_mps, summary.peak_fist_speed_mps, "the right fist's peak, reached before contact");
        assert!(hits[0].position.z > 0.3, "the hit is where the fist met the bag: {:?}", hits[0].position);
        assert_eq!(hits[0].collider, FAKE_BAG_ID);
    }

    /// Plays frames of a still character (fists where the fake world starts them) with the given touches.
    fn hits_of(frames: &[Vec<Touch>]) -> (Vec<Hit>, PunchSummary) {
        let world = FakeWorld::new(1);
        let mut punch = Punch::new(rest_geometry(), PolicySpec::new(5, 50, 1).expect("valid"), false);
        let mut hits = Vec::new();
        for touches in frames {
            let (hit, sensed) = punch.sense(world.read_slot(0), touches);
            hits.extend(hit);
            let mean = matches!(sensed, Sensed::Decide(_)).then_some([0.0; 10]);
            punch.act(mean.as_ref().map(|m| &m[..]), &mut RuntimeNoise::new(0, 0.0, -1)).expect("acts");
        }
        (hits, punch.interrupt().0)
    }

    fn fist_touch(collider: u64, impulse_ns: f32) -> Touch {
        let fist =
            FakeWorld::new(1).read_slot(0).bodies[Body::ForearmR.index()].position + rest_geometry().fist_offsets[0];
        Touch { body: Body::ForearmR.index(), collider, point: fist, impulse: Vec3::Z * impulse_ns, overlap: false }
    }

    #[test]
    fn a_punch_hits_each_thing_once_however_its_contacts_come_and_go() {
        // As Jolt reports a punch on the sandbag: a strong first frame, zero-impulse frames while the fist
        // stays in contact, a second push, then nothing; then the fist touches it again (the bag swinging
        // back, or the fist at an Area3D's edge), harder, and touches a second body.
        let frames: Vec<Vec<Touch>> = [3.0, 0.0, 0.0, 0.14, 0.13, 0.0]
            .iter()
            .map(|&impulse| vec![fist_touch(1, impulse), fist_touch(1, impulse / 2.0)])
            .chain([vec![], vec![fist_touch(1, 6.0)], vec![], vec![fist_touch(2, 2.0)]])
            .collect();
        let (hits, summary) = hits_of(&frames);
        let colliders: Vec<u64> = hits.iter().map(|h| h.collider).collect();
        assert_eq!(colliders, [1, 2], "one hit per thing, not per contact episode: {hits:?}");
        assert!((hits[0].impulse_ns() - 4.5).abs() < 1e-5);
        assert_eq!(summary.hits, 2);
        assert!((summary.strongest_hit_ns - 6.0).abs() < 1e-5, "a later contact still counts as an impact");
        assert!(summary.interrupted && summary.frames == frames.len());
        assert_eq!(summary.first_struck, Some(1), "the first thing the punching fist struck");
    }

    #[test]
    fn a_punch_whose_guard_fist_alone_strikes_something_struck_nothing() {
        let guard_fist = |collider: u64| {
            let world = FakeWorld::new(1);
            let fist = world.read_slot(0).bodies[Body::ForearmL.index()].position + rest_geometry().fist_offsets[1];
            Touch { body: Body::ForearmL.index(), collider, point: fist, impulse: Vec3::Z * 3.0, overlap: false }
        };
        let (hits, summary) = hits_of(&[vec![guard_fist(7)], vec![]]);
        assert_eq!((hits.len(), hits[0].hand), (1, Hand::Left), "the guard hand's hit is still a hit: {hits:?}");
        assert_eq!(summary.first_struck, None, "but the punch whiffed");
        let (_, summary) = hits_of(&vec![vec![]; 3]);
        assert_eq!(summary.first_struck, None);
    }

    #[test]
    fn the_punching_fists_peak_speed_is_its_own_and_the_off_fists_comes_apart() {
        let mut reading = FakeWorld::new(1).read_slot(0);
        reading.bodies[Body::ForearmL.index()].linear_velocity = Vec3::new(0.0, 9.0, 0.0); // a flailing guard
        reading.bodies[Body::ForearmR.index()].linear_velocity = Vec3::new(0.0, 0.0, 3.0);
        let mut punch = Punch::new(rest_geometry(), PolicySpec::new(5, 50, 1).expect("valid"), false);
        let (hits, _) = punch.sense(reading, &[fist_touch(1, 1.0)]);
        let summary = punch.interrupt().0;
        assert!((summary.peak_fist_speed_mps - 3.0).abs() < 1e-4, "{summary:?}");
        assert!((summary.peak_off_fist_speed_mps - 9.0).abs() < 1e-4, "{summary:?}");
        assert!((hits[0].speed_mps - 3.0).abs() < 1e-4, "the striking fist's speed: {hits:?}");
    }

    #[test]
    fn a_left_hand_punch_is_the_right_hands_in_the_mirrored_world() {
        // The fake world is symmetric about the character's sagittal plane and its bag sits on it, so the same
        // policy played with the left hand senses, records and scores what the right hand's punch does.
        let spec = PolicySpec::new(5, 50, 1).expect("valid");
        let elbow = |_: &[f32; OBS_DIM]| {
            let mut action = vec![0.0; DOF_COUNT];
            action[5] = 0.6; // the punching elbow straightens; the rest hold the guard
            action
        };
        let right = play_with_hand(Hand::Right, spec, &mut RuntimeNoise::new(0, 0.0, -1), elbow);
        let left = play_with_hand(Hand::Left, spec, &mut RuntimeNoise::new(0, 0.0, -1), elbow);
        for (index, (a, b)) in right.1.features.iter().zip(&left.1.features).enumerate() {
            let name = crate::contract::sensing::FEATURE_NAMES[index % FEATURE_COUNT];
            assert!(
                (a - b).abs() < 1e-4,
                "frame {}: {name} is {a} right-handed, {b} left-handed",
                index / FEATURE_COUNT
            );
        }
        assert_eq!(right.1.observations.len(), left.1.observations.len());
        assert_eq!(right.2.len(), 1);
        assert_eq!((right.2[0].hand, left.2.len(), left.2[0].hand), (Hand::Right, 1, Hand::Left));
        assert!((left.2[0].position.x + right.2[0].position.x).abs() < 1e-4, "the hit is at the mirrored place");
        assert!((right.3.peak_fist_speed_mps - left.3.peak_fist_speed_mps).abs() < 1e-4);
    }

    #[test]
    fn what_counts_as_a_hit() {
        let mut far = fist_touch(2, 5.0);
        far.point += Vec3::X * 0.2;
        let mut upper_arm = fist_touch(3, 5.0);
        upper_arm.body = Body::UpperArmR.index();
        let area = Touch { overlap: true, impulse: Vec3::ZERO, ..fist_touch(4, 0.0) };
        let (hits, _) = hits_of(&[vec![far, upper_arm, fist_touch(5, 0.01)], vec![area, fist_touch(6, 1.0)]]);
        let colliders: Vec<u64> = hits.iter().map(|h| h.collider).collect();
        assert_eq!(colliders, [4, 6], "contacts away from the fist, off the forearms or too light are not hits");
    }

    #[test]
    fn recovery_drives_back_to_guard_and_stops_there() {
        let mut reading = FakeWorld::new(1).read_slot(0);
        assert_eq!(Recovery::new(rest_geometry(), [0.0; DOF_COUNT]).step(&reading), None, "already in guard");
        let stance = Recovery::new(rest_geometry(), crate::contract::stance::Stance::Orthodox.guard_targets());
        let commands = stance.clone().step(&reading).expect("the square guard is not the stance's");
        assert!(commands[0].length() > 1.0, "the waist is driven round: {commands:?}");
        reading.bodies[Body::ForearmR.index()].rotation = Quat::from_rotation_x(0.5);
        let mut recovery = Recovery::new(rest_geometry(), [0.0; DOF_COUNT]);
        let commands = recovery.step(&reading).expect("drives");
        assert!(commands[2].length() > 1.0, "the right elbow is driven back: {commands:?}");
        let steps = std::iter::from_fn(|| recovery.step(&reading)).take(1000).count();
        assert_eq!(steps + 1, Recovery::MAX_FRAMES as usize, "a recovery that cannot settle ends on time");
    }

    #[test]
    fn a_return_before_a_punch_ends_within_the_moves_tolerance() {
        // The right elbow 0.05 rad off its guard angle, at rest.
        let mut reading = FakeWorld::new(1).read_slot(0);
        reading.bodies[Body::ForearmR.index()].rotation = Quat::from_rotation_x(0.05);
        let ready = |angle_rad: f32| Recovery::new(rest_geometry(), [0.0; DOF_COUNT]).ready_to_punch(angle_rad);
        assert_eq!(ready(Recovery::READY_ANGLE_RAD).step(&reading), None, "near enough for the default tolerance");
        assert!(ready(Recovery::SETTLED_ANGLE_RAD).step(&reading).is_some(), "not for a settled start");
        assert!(ready(f32::NAN).step(&reading).is_some(), "a tolerance that is not a number is the settled one");
        // Within the angle but still moving faster than ten times it per second: not yet.
        reading.bodies[Body::ForearmR.index()].angular_velocity = Vec3::X * 1.5;
        assert!(ready(Recovery::READY_ANGLE_RAD).step(&reading).is_some(), "still swinging back");
        assert_eq!(ready(0.2).step(&reading), None, "a wider tolerance allows a faster joint too");
    }

    #[test]
    fn a_recovery_after_a_hit_waits_for_the_head_to_come_back_on_its_neck() {
        let mut reading = FakeWorld::new(1).read_slot(0);
        let frames_first = Recovery::AFTER_HIT_FRAMES.0 as usize;
        let mut recovery = Recovery::new(rest_geometry(), [0.0; DOF_COUNT]).after_hit();
        let steps = std::iter::from_fn(|| recovery.step(&reading)).take(1000).count();
        assert_eq!(steps, frames_first, "in guard with the head at rest: back after the least time");
        // The driven joints in guard, the head snapped 17 degrees to the side on the chest.
        reading.bodies[Body::Head.index()].rotation =
            Quat::from_rotation_z(0.3) * reading.bodies[Body::Head.index()].rotation;
        let mut struck = Recovery::new(rest_geometry(), [0.0; DOF_COUNT]).after_hit();
        let steps = std::iter::from_fn(|| struck.step(&reading)).take(1000).count();
        assert_eq!(steps, Recovery::AFTER_HIT_FRAMES.1 as usize, "not back while the head is turned");
        // Turned less than the threshold but still swinging: not yet; at rest there: back.
        reading.bodies[Body::Head.index()].rotation =
            Quat::from_rotation_z(0.05) * FakeWorld::new(1).read_slot(0).bodies[Body::Head.index()].rotation;
        reading.bodies[Body::Head.index()].angular_velocity = Vec3::Z * 2.0;
        assert!(Recovery::new(rest_geometry(), [0.0; DOF_COUNT]).after_hit().holding_back(&reading, frames_first));
        reading.bodies[Body::Head.index()].angular_velocity = Vec3::ZERO;
        assert!(!Recovery::new(rest_geometry(), [0.0; DOF_COUNT]).after_hit().holding_back(&reading, frames_first));
        // A recovery after a punch looks at the driven joints alone.
        reading.bodies[Body::Head.index()].rotation = Quat::from_rotation_z(0.3);
        assert_eq!(Recovery::new(rest_geometry(), [0.0; DOF_COUNT]).step(&reading), None);
    }

    #[test]
    fn noise_goes_on_the_first_k_decisions_only() {
        let spec = PolicySpec::new(5, 50, 1).expect("valid");
        let (_, record, _, _) = play(spec, &mut RuntimeNoise::new(3, 0.3, 4), forward, |_, _| {});
        for (decision, (played, mean)) in record.actions.chunks(10).zip(record.mean_actions.chunks(10)).enumerate() {
            assert_eq!(played != mean, decision < 4, "decision {decision}");
        }
    }

    #[test]
    fn a_sigma_changed_mid_punch_applies_from_the_next_decision() {
        let spec = PolicySpec::new(5, 50, 1).expect("valid");
        // Raised six frames in, as an inspector would: decision 1 (frames 5-9) is already decided.
        let raise = |frame: u32, noise: &mut RuntimeNoise| {
            if frame == 6 {
                noise.sigma = 0.8;
            }
        };
        let (_, record, _, _) = play(spec, &mut RuntimeNoise::new(1, 0.0, -1), forward, raise);
        let noisy: Vec<bool> =
            record.actions.chunks(10).zip(record.mean_actions.chunks(10)).map(|(a, m)| a != m).collect();
        assert_eq!(noisy, [false, false, true, true, true, true, true, true, true, true]);
    }

    #[test]
    fn a_policys_noise_scale_spreads_the_noise_over_its_degrees_of_freedom() {
        let spec = PolicySpec::new(5, 50, 1).expect("valid");
        let mut scale = UNIFORM_NOISE;
        scale[6..].fill(0.0); // the guard arm held still
        scale[0] = 0.5;
        let uniform = play(spec, &mut RuntimeNoise::new(5, 0.3, -1), forward, |_, _| {}).1;
        let (_, scaled, _, _) = play_scaled(spec, scale, &mut RuntimeNoise::new(5, 0.3, -1), forward, |_, _| {});
        for ((played, mean), uniform) in
            scaled.actions.chunks(10).zip(scaled.mean_actions.chunks(10)).zip(uniform.actions.chunks(10))
        {
            assert_eq!(played[6..], mean[6..]);
            assert!(played[1..6].iter().zip(&mean[1..6]).all(|(p, m)| p != m));
            // The same samples, scaled: half the uniform punch's deviation on the waist's flexion.
            assert!(((played[0] - mean[0]) - 0.5 * (uniform[0] - mean[0])).abs() < 1e-6);
            assert_eq!(played[1..6], uniform[1..6]);
        }
    }

    #[test]
    fn seeds_make_punches_repeat_or_differ() {
        let spec = PolicySpec::new(5, 50, 3).expect("valid");
        let actions = |seed: u64| play(spec, &mut RuntimeNoise::new(seed, 0.3, -1), forward, |_, _| {}).1.actions;
        assert_eq!(actions(7), actions(7));
        assert_ne!(actions(7), actions(8));
    }

    #[test]
    fn a_nan_mean_is_an_error_not_a_motion() {
        let mut punch = Punch::new(rest_geometry(), PolicySpec::new(5, 50, 1).expect("valid"), false);
        let mut world = FakeWorld::new(1);
        let (_, sensed) = punch.sense(world.read_slot(0), &[]);
        assert!(matches!(sensed, Sensed::Decide(_)));
        let error = punch.act(Some(&[f32::NAN; 10]), &mut RuntimeNoise::new(0, 0.0, -1)).expect_err("refused");
        assert!(error.to_string().contains("NaN"), "{error}");
        assert!(punch.act(Some(&[0.0; 3]), &mut RuntimeNoise::new(0, 0.0, -1)).is_err(), "wrong width");
        world.step();
    }
}
