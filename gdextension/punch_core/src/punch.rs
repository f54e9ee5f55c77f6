//! One punch of a game character, free of Godot: the per-decision clock, the designer's runtime noise
//! (which decisions get it, from which seed), hit detection, the punch's record and its end.
//!
//! `PunchController` (punch_godot) only moves data across: each physics frame it hands `Punch::sense` the
//! frame just simulated, runs the policy on the observation when one is asked for (batched with other
//! controllers), and hands the mean action to `Punch::act`, whose motor commands it applies. The training
//! server's `Session` drives the same `CharacterController` in lockstep over many slots.

use glam::Vec3;

use crate::character::Body;
use crate::controller::CharacterController;
use crate::error::{CoreError, CoreResult};
use crate::noise::GaussianNoise;
use crate::observation::{OBS_DIM, observation};
use crate::sensing::{CharacterGeometry, FEATURE_COUNT, FrameReading, columns, feature_vector};
use crate::spec::PolicySpec;

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

    /// The action played at decision `index`: the mean plus noise when the decision is noisy. The noise
    /// sequence advances only on noisy decisions.
    pub fn apply(&mut self, decision: u32, mean: &[f32]) -> Vec<f32> {
        if !self.is_noisy(decision) {
            return mean.to_vec();
        }
        mean.iter().map(|m| m + self.sigma * self.rng.sample()).collect()
    }
}

/// A fist started touching the target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Contact impulse on the target, N s.
    pub impulse_ns: f32,
    /// The fist's peak speed so far in this punch, m/s.
    pub speed_mps: f32,
    /// Where the fist was (world coordinates).
    pub position: Vec3,
}

/// What a finished punch did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PunchSummary {
    pub frames: usize,
    pub peak_fist_speed_mps: f32,
    pub hits: i64,
    pub strongest_hit_ns: f32,
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
    fist_offsets: [Vec3; 2],
    spec: PolicySpec,
    frame: u32,
    /// This frame's reading, kept from sensing to acting.
    reading: FrameReading,
    touching: bool,
    summary: PunchSummary,
    record: Option<PunchRecord>,
}

impl Punch {
    /// A punch of a character with `geometry`, timed and smoothed as `spec` says; with `record`, it keeps
    /// its `PunchRecord`.
    pub fn new(geometry: CharacterGeometry, spec: PolicySpec, record: bool) -> Self {
        Self {
            controller: CharacterController::new(geometry, spec.smoothing_window as usize),
            fist_offsets: geometry.fist_offsets,
            spec,
            frame: 0,
            reading: FrameReading::default(),
            touching: false,
            summary: PunchSummary::default(),
            record: record.then(PunchRecord::default),
        }
    }

    /// Physics frames played so far.
    pub fn frame(&self) -> u32 {
        self.frame
    }

    /// The decision the current frame belongs to.
    pub fn decision(&self) -> u32 {
        self.frame / self.spec.decision_period
    }

    /// First half of a physics frame: reads the frame just simulated. Returns the hit it shows (when a fist
    /// started touching the target) and what the caller does next.
    pub fn sense(&mut self, reading: FrameReading) -> (Option<Hit>, Sensed) {
        let features = self.controller.features(&reading);
        let hit = self.track_hits(&features, &reading);
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
            let action = noise.apply(self.decision(), mean);
            self.controller.set_action(&action)?;
            if let Some(record) = self.record.as_mut() {
                record.mean_actions.extend_from_slice(mean);
                record.actions.extend_from_slice(&action);
            }
        }
        let commands = self.controller.motor_commands(&self.reading);
        self.frame += 1;
        Ok(commands)
    }

    fn track_hits(&mut self, features: &[f32; FEATURE_COUNT], reading: &FrameReading) -> Option<Hit> {
        let length = |column: usize| feature_vector(features, column).length();
        let speeds = [length(columns::FIST_R_VEL), length(columns::FIST_L_VEL)];
        let impulses = [length(columns::FIST_R_IMPULSE), length(columns::FIST_L_IMPULSE)];
        let previous_peak = self.summary.peak_fist_speed_mps;
        self.summary.peak_fist_speed_mps = previous_peak.max(speeds[0]).max(speeds[1]);
        let side = if impulses[0] >= impulses[1] { 0 } else { 1 };
        let touching = impulses[side] > HIT_IMPULSE_NS;
        let started = touching && !self.touching;
        self.touching = touching;
        if !started {
            return None;
        }
        self.summary.hits += 1;
        self.summary.strongest_hit_ns = self.summary.strongest_hit_ns.max(impulses[side]);
        let forearm = &reading.bodies[[Body::ForearmR, Body::ForearmL][side].index()];
        Some(Hit {
            impulse_ns: impulses[side],
            speed_mps: previous_peak.max(speeds[side]),
            position: forearm.position + forearm.rotation * self.fist_offsets[side],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fake_world::{FakeWorld, rest_geometry};

    /// Plays one punch on a fake world with a policy given as a closure; returns the decisions' frame
    /// indices, the actions played, the hits and the end.
    fn play(
        spec: PolicySpec,
        noise: &mut RuntimeNoise,
        mut policy: impl FnMut(&[f32; OBS_DIM]) -> Vec<f32>,
        mut between_frames: impl FnMut(u32, &mut RuntimeNoise),
    ) -> (Vec<u32>, PunchRecord, Vec<Hit>, PunchSummary) {
        let mut world = FakeWorld::new(1);
        let mut punch = Punch::new(rest_geometry(), spec, true);
        let (mut decided_at, mut hits) = (Vec::new(), Vec::new());
        loop {
            let (hit, sensed) = punch.sense(world.read_slot(0));
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
    fn the_fake_punch_hits_once_per_contact_and_reports_it() {
        let spec = PolicySpec::new(5, 50, 1).expect("valid");
        let (_, _, hits, summary) = play(spec, &mut RuntimeNoise::new(0, 0.0, -1), forward, |_, _| {});
        assert_eq!(hits.len(), 1, "the fist stays on the bag: one hit, not one per frame");
        assert_eq!(summary.hits, 1);
        assert!(summary.strongest_hit_ns > HIT_IMPULSE_NS && summary.peak_fist_speed_mps > 0.0);
        assert!(hits[0].position.z > 0.3, "the hit is where the fist met the bag: {:?}", hits[0].position);
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
        let (_, sensed) = punch.sense(world.read_slot(0));
        assert!(matches!(sensed, Sensed::Decide(_)));
        let error = punch.act(Some(&[f32::NAN; 10]), &mut RuntimeNoise::new(0, 0.0, -1)).expect_err("refused");
        assert!(error.to_string().contains("NaN"), "{error}");
        assert!(punch.act(Some(&[0.0; 3]), &mut RuntimeNoise::new(0, 0.0, -1)).is_err(), "wrong width");
        world.step();
    }
}
