//! What a game's punch controller does with its character, free of Godot: the phases (idle, returning to
//! guard before a punch, punching, recovering), the runtime noise that makes each punch differ, and the
//! events the game hears of, in the order they happened.
//!
//! The promise kept here: every `Event::Started` is followed by exactly one `Event::Finished`, however the
//! punch ends (its last frame, a new punch, `cancel`, an error, the controller leaving the game). The Godot
//! layer (`PunchController`) reads the engine into `FrameReading`s and `Touch`es, drives the joints with the
//! commands it gets back, and turns each event into a signal, one at a time (`next_event`), so that a signal
//! handler that starts another punch hears of the first one's end before the second one's start.

use std::collections::VecDeque;

use glam::Vec3;

use crate::contract::character::DOF_COUNT;
use crate::contract::observation::OBS_DIM;
use crate::contract::sensing::{CharacterGeometry, FrameReading};
use crate::error::CoreResult;
use crate::game::moves::{Hand, Move};
use crate::game::punch::{Hit, Punch, PunchRecord, PunchSummary, Recovery, RuntimeNoise, Sensed, Touch};

/// Joint motor commands for one physics step (`Body` joint order).
pub type MotorCommands = [Vec3; 5];

/// Something the game hears of (a signal of `PunchController`).
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A punch began: the hand that throws it and the move it is (None: a policy played as it is).
    Started { hand: Hand, punch_move: Option<Move> },
    /// The punch just started goes at the nearest point the policy covers: the target was outside its reach
    /// volume. The target's offset in the character's frame, and that point (world coordinates).
    OutOfReach { offset: Vec3, nearest: Vec3 },
    /// A fist struck something for the first time in this punch.
    Hit(Hit),
    /// The punch is over.
    Finished(PunchSummary, Ending),
    /// The character is back in its guard pose (or the recovery's time is up).
    Recovered,
}

/// How a punch ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// It played its last frame.
    Completed,
    /// It was ended early: cancelled, replaced by another punch, or its controller left the game.
    Interrupted,
    /// It stopped on an error (the message says which).
    Error(String),
}

/// What the caller does with the joints after `act`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Drive {
    /// Nothing: the controller is idle and leaves the joints as they are.
    Nothing,
    /// Drive the joint motors at these velocities for the next step.
    Motors(MotorCommands),
    /// Stop the joint motors: the character holds its pose.
    Hold,
}

/// What the caller reads next after `begin_frame`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrameNeeds {
    /// Nothing more this frame: call `act(None)`.
    Nothing,
    /// A punch plays this frame: read the target and what the fists touch, then call `sense`.
    Target,
}

/// The runtime noise settings a designer may change at any time: they apply from the next decision
/// (`sigma`, `noisy_decisions`) or the next punch (`seed`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseSettings {
    pub seed: i64,
    pub sigma: f32,
    /// Noise on the first k decisions of a punch only; -1 on every decision.
    pub noisy_decisions: i32,
}

/// A punch to start: its first state and the policy that plays it (kept by the punch: a policy given later
/// plays from the next punch).
pub struct PunchStart<P> {
    pub punch: Punch,
    pub policy: P,
    /// Return to guard first (the character is away from it: the end of an earlier punch, mid-recovery).
    pub guard_first: bool,
    pub out_of_reach: Option<(Vec3, Vec3)>,
}

enum Phase<P> {
    Idle,
    /// Returning to guard before the punch starts; the motor commands for the next step.
    Guarding(Box<Punch>, P, Box<Recovery>, MotorCommands),
    Punching(Box<Punch>, P),
    /// Returning to guard after a punch or on request; the motor commands for the next step.
    Recovering(Box<Recovery>, MotorCommands),
}

/// The punches of one controller. `P` is the policy handle a decision is asked of (shared, so cloned).
pub struct Lifecycle<P: Clone> {
    phase: Phase<P>,
    /// The noise of the sequence of punches from one seed and policy ...
    noise: RuntimeNoise,
    /// ... that seed and the policy's identity (None: the next punch starts a new sequence).
    noise_key: Option<(i64, usize)>,
    events: VecDeque<Event>,
    /// The joints are to be stopped at the next `act` (a recovery ended, or a punch stopped).
    hold_next: bool,
    last_record: PunchRecord,
    /// The guard a recovery drives to (rad, action order; all 0: the square guard).
    guard: [f32; DOF_COUNT],
}

impl<P: Clone> Default for Lifecycle<P> {
    fn default() -> Self {
        Self {
            phase: Phase::Idle,
            noise: RuntimeNoise::new(0, 0.0, -1),
            noise_key: None,
            events: VecDeque::new(),
            hold_next: false,
            last_record: PunchRecord::default(),
            guard: [0.0; DOF_COUNT],
        }
    }
}

impl<P: Clone> Lifecycle<P> {
    /// True while a punch runs (including its return to guard first).
    pub fn is_punching(&self) -> bool {
        matches!(self.phase, Phase::Punching(..) | Phase::Guarding(..))
    }

    /// True while the character returns to its guard pose (not before a punch).
    pub fn is_recovering(&self) -> bool {
        matches!(self.phase, Phase::Recovering(..))
    }

    /// True while the controller drives its character, or has something left to say or do: the game must
    /// keep calling `begin_frame` and `act`, and taking the events.
    pub fn is_active(&self) -> bool {
        !matches!(self.phase, Phase::Idle) || self.hold_next || !self.events.is_empty()
    }

    /// The guard every later recovery drives to, and a punch returns to first (`PunchStart::guard_first`): joint
    /// targets (rad, action order), all 0 for the square guard, a stance's (`Stance::guard_targets`) otherwise.
    pub fn set_guard(&mut self, guard: [f32; DOF_COUNT]) {
        self.guard = guard;
    }

    /// The record of the last finished punch (empty unless its `Punch` was made to record).
    pub fn last_record(&self) -> &PunchRecord {
        &self.last_record
    }

    /// The next event to tell the game, oldest first.
    pub fn next_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// Starts a punch; one that is running ends first (interrupted). `identity` tells policies apart for
    /// the noise: a new seed or a new policy starts a new sequence of punches.
    pub fn start(&mut self, start: PunchStart<P>, identity: usize, noise: NoiseSettings) {
        self.interrupt();
        if self.noise_key != Some((noise.seed, identity)) {
            self.noise = RuntimeNoise::new(noise.seed as u64, noise.sigma, noise.noisy_decisions);
            self.noise_key = Some((noise.seed, identity));
        }
        let punch = Box::new(start.punch);
        let (hand, punch_move) = (punch.hand(), punch.punch_move());
        let geometry = *punch.geometry();
        self.phase = match start.guard_first {
            // Decided at the next frame's reading: a character already in guard punches in that same frame.
            true => {
                Phase::Guarding(punch, start.policy, Box::new(Recovery::new(geometry, self.guard)), [Vec3::ZERO; 5])
            }
            false => Phase::Punching(punch, start.policy),
        };
        self.hold_next = false;
        self.events.push_back(Event::Started { hand, punch_move });
        if let Some((offset, nearest)) = start.out_of_reach {
            self.events.push_back(Event::OutOfReach { offset, nearest });
        }
    }

    /// Ends a running punch early (`Finished`, interrupted); the joints then hold. Nothing when none runs.
    pub fn interrupt(&mut self) {
        self.end_punch(Ending::Interrupted);
    }

    /// Ends what runs on an error: a punch with `Finished` and the message (the next punch starts a new
    /// noise sequence), a recovery where it is. The joints then hold.
    pub fn fail(&mut self, error: &str) {
        if self.end_punch(Ending::Error(error.to_string())) {
            self.noise_key = None;
        } else if self.is_recovering() {
            self.phase = Phase::Idle;
            self.hold_next = true;
        }
    }

    /// Ends the punch or recovery that is running; the joints then hold the pose they are in.
    pub fn cancel(&mut self) {
        self.interrupt();
        if matches!(std::mem::replace(&mut self.phase, Phase::Idle), Phase::Recovering(..)) {
            self.hold_next = true;
        }
    }

    /// Drives the character back to its guard pose (ending a punch that is running); `Recovered` comes
    /// when it is there.
    pub fn recover(&mut self, geometry: CharacterGeometry) {
        self.interrupt();
        self.phase = Phase::Recovering(Box::new(Recovery::new(geometry, self.guard)), [Vec3::ZERO; 5]);
        self.hold_next = false;
    }

    /// First half of a physics frame: the character's bodies were just read into `reading`. Steps a
    /// return to guard; says whether a punch plays this frame (the caller then reads the target and calls
    /// `sense`).
    pub fn begin_frame(&mut self, reading: &FrameReading) -> FrameNeeds {
        match &mut self.phase {
            Phase::Idle => FrameNeeds::Nothing,
            Phase::Recovering(recovery, commands) => {
                match recovery.step(reading) {
                    Some(next) => *commands = next,
                    None => {
                        self.phase = Phase::Idle;
                        self.hold_next = true;
                        self.events.push_back(Event::Recovered);
                    }
                }
                FrameNeeds::Nothing
            }
            Phase::Guarding(_, _, recovery, commands) => match recovery.step(reading) {
                Some(next) => {
                    *commands = next;
                    FrameNeeds::Nothing
                }
                None => {
                    // In guard: the punch starts with this frame.
                    if let Phase::Guarding(punch, policy, ..) = std::mem::replace(&mut self.phase, Phase::Idle) {
                        self.phase = Phase::Punching(punch, policy);
                    }
                    FrameNeeds::Target
                }
            },
            Phase::Punching(..) => FrameNeeds::Target,
        }
    }

    /// The fists' world positions and velocities in `reading` while a punch plays ([right, left]), for a
    /// game that looks for areas they overlap.
    pub fn fists(&self, reading: &FrameReading) -> Option<[(Vec3, Vec3); 2]> {
        match &self.phase {
            Phase::Punching(punch, _) => Some(punch.fists(reading)),
            _ => None,
        }
    }

    /// Second step of a punching frame: the full reading (target included) and what the fists touch. Returns
    /// the decision to ask of the policy when one is due. After the punch's last frame it ends (`Finished`)
    /// and, when `recover_at` gives the character's geometry, the character returns to guard.
    pub fn sense(
        &mut self,
        reading: FrameReading,
        touches: &[Touch],
        recover_at: impl FnOnce() -> Option<CharacterGeometry>,
    ) -> Option<(P, Box<[f32; OBS_DIM]>)> {
        let Phase::Punching(punch, policy) = &mut self.phase else { return None };
        let (hits, sensed) = punch.sense(reading, touches);
        self.events.extend(hits.into_iter().map(Event::Hit));
        match sensed {
            Sensed::Hold => None,
            Sensed::Decide(observation) => Some((policy.clone(), observation)),
            Sensed::Finished(summary, record) => {
                self.events.push_back(Event::Finished(summary, Ending::Completed));
                self.last_record = record.unwrap_or_default();
                self.phase = Phase::Idle;
                self.hold_next = true;
                if let Some(geometry) = recover_at() {
                    let mut recovery = Recovery::new(geometry, self.guard);
                    if let Some(commands) = recovery.step(&reading) {
                        self.phase = Phase::Recovering(Box::new(recovery), commands);
                        self.hold_next = false;
                    }
                }
                None
            }
        }
    }

    /// Second half of a physics frame: the decision's mean action when `sense` asked for one, with the noise
    /// settings of now. Returns what to do with the joints for the next step. A mean that cannot be played
    /// (not finite, misshapen) ends the punch with that error, returned for the caller to report; the joints
    /// then hold. (A failed inference is the caller's to report: `fail`, then `act(None, ..)`.)
    pub fn act(&mut self, mean: Option<&[f32]>, noise: NoiseSettings) -> CoreResult<Drive> {
        let drive = match &mut self.phase {
            Phase::Idle => Drive::Nothing,
            Phase::Recovering(_, commands) | Phase::Guarding(_, _, _, commands) => Drive::Motors(*commands),
            Phase::Punching(punch, _) => {
                // A designer may change these at any time: they apply from the next decision.
                self.noise.sigma = noise.sigma;
                self.noise.noisy_decisions = noise.noisy_decisions;
                match punch.act(mean, &mut self.noise) {
                    Ok(commands) => Drive::Motors(commands),
                    Err(error) => {
                        self.fail(&error.to_string());
                        self.hold_next = false;
                        return Err(error);
                    }
                }
            }
        };
        Ok(match std::mem::take(&mut self.hold_next) {
            true if drive == Drive::Nothing => Drive::Hold,
            _ => drive,
        })
    }

    /// Ends a running punch with `ending`; true when one was running.
    fn end_punch(&mut self, ending: Ending) -> bool {
        if !self.is_punching() {
            return false;
        }
        let (Phase::Punching(punch, _) | Phase::Guarding(punch, ..)) = std::mem::replace(&mut self.phase, Phase::Idle)
        else {
            return false;
        };
        let (summary, record) = punch.interrupt();
        self.last_record = record.unwrap_or_default();
        self.events.push_back(Event::Finished(summary, ending));
        self.hold_next = true;
        true
    }
}

#[cfg(test)]
mod tests {
    use glam::Quat;
    use proptest::prelude::*;

    use super::*;
    use crate::contract::character::Body;
    use crate::contract::spec::PolicySpec;
    use crate::error::CoreError;
    use crate::fake_world::{FAKE_BAG_ID, FakeWorld, rest_geometry};

    /// Policies are numbers here: the lifecycle only hands them back with each decision.
    type Policy = u8;

    const CALM: NoiseSettings = NoiseSettings { seed: 0, sigma: 0.0, noisy_decisions: -1 };

    fn start(policy: Policy, guard_first: bool) -> PunchStart<Policy> {
        let spec = PolicySpec::new(5, 50, 1).expect("valid");
        PunchStart { punch: Punch::new(rest_geometry(), spec, true), policy, guard_first, out_of_reach: None }
    }

    /// One physics frame of the fake world as `PunchController` plays it; returns the policy asked (if a
    /// decision was due) and what was driven. `decide` plays the policy (an error ends the punch).
    fn frame(
        lifecycle: &mut Lifecycle<Policy>,
        world: &mut FakeWorld,
        noise: NoiseSettings,
        decide: impl FnOnce(Policy) -> Result<Vec<f32>, CoreError>,
    ) -> (Option<Policy>, Drive) {
        let reading = world.read_slot(0);
        let mut asked = None;
        let mut mean = None;
        if lifecycle.begin_frame(&reading) == FrameNeeds::Target
            && let Some((policy, _observation)) = lifecycle.sense(reading, &world.touches_slot(0), || None)
        {
            asked = Some(policy);
            match decide(policy) {
                Ok(decided) => mean = Some(decided),
                Err(error) => lifecycle.fail(&error.to_string()),
            }
        }
        let drive = lifecycle.act(mean.as_deref(), noise).unwrap_or(Drive::Hold);
        if let Drive::Motors(commands) = drive {
            world.drive_slot(0, &commands);
        }
        world.step();
        (asked, drive)
    }

    fn forward(_: Policy) -> Result<Vec<f32>, CoreError> {
        Ok(vec![0.6; 10])
    }

    fn events(lifecycle: &mut Lifecycle<Policy>) -> Vec<Event> {
        std::iter::from_fn(|| lifecycle.next_event()).collect()
    }

    #[test]
    fn a_punch_from_guard_starts_at_once_plays_its_frames_and_ends_once() {
        let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
        lifecycle.start(start(3, true), 3, CALM);
        assert!(lifecycle.is_punching());
        let mut decided_at = Vec::new();
        for index in 0..60 {
            let (asked, _) = frame(&mut lifecycle, &mut world, CALM, forward);
            if let Some(policy) = asked {
                assert_eq!(policy, 3);
                decided_at.push(index);
            }
        }
        assert_eq!(decided_at, (0..50).step_by(5).collect::<Vec<_>>(), "a character in guard punches at once");
        let events = events(&mut lifecycle);
        assert_eq!(events[0], Event::Started { hand: Hand::Right, punch_move: None });
        assert!(matches!(events[1], Event::Hit(hit) if hit.collider == FAKE_BAG_ID));
        let Event::Finished(summary, Ending::Completed) = &events[2] else { panic!("{events:?}") };
        assert_eq!((summary.frames, summary.hits, events.len()), (50, 1, 3));
        assert!(!lifecycle.is_active() && lifecycle.last_record().observations.len() == 10 * OBS_DIM);
    }

    #[test]
    fn a_new_punch_ends_the_running_one_first_and_plays_its_own_policy() {
        let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
        lifecycle.start(start(1, false), 1, CALM);
        let asked: Vec<_> = (0..12).filter_map(|_| frame(&mut lifecycle, &mut world, CALM, forward).0).collect();
        assert_eq!(asked, [1, 1, 1]);
        lifecycle.start(start(2, false), 2, CALM);
        let asked: Vec<_> = (0..12).filter_map(|_| frame(&mut lifecycle, &mut world, CALM, forward).0).collect();
        assert_eq!(asked, [2, 2, 2], "the new punch asks its own policy");
        let ends: Vec<_> = events(&mut lifecycle).into_iter().filter(|e| !matches!(e, Event::Hit(_))).collect();
        assert!(
            matches!(&ends[..], [Event::Started { .. }, Event::Finished(summary, Ending::Interrupted), Event::Started { .. }]
                if summary.frames == 12 && summary.interrupted),
            "{ends:?}"
        );
    }

    #[test]
    fn an_inference_error_ends_the_punch_with_its_message_and_the_joints_hold() {
        let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
        lifecycle.start(start(1, false), 1, CALM);
        let failing = |_| Err(CoreError::Inference("boom".into()));
        assert_eq!(frame(&mut lifecycle, &mut world, CALM, failing), (Some(1), Drive::Hold));
        assert_eq!(frame(&mut lifecycle, &mut world, CALM, forward), (None, Drive::Nothing));
        let events = events(&mut lifecycle);
        assert!(
            matches!(&events[1], Event::Finished(_, Ending::Error(message)) if message.contains("boom")),
            "{events:?}"
        );
        let nan = |_| Ok(vec![f32::NAN; 10]);
        lifecycle.start(start(1, false), 1, CALM);
        assert_eq!(frame(&mut lifecycle, &mut world, CALM, nan).1, Drive::Hold, "a NaN action never drives a joint");
        assert!(matches!(events_of_kind(&mut lifecycle)[..], [_, Ending::Error(_)]));
    }

    fn events_of_kind(lifecycle: &mut Lifecycle<Policy>) -> Vec<Ending> {
        events(lifecycle)
            .into_iter()
            .filter_map(|e| match e {
                Event::Finished(_, ending) => Some(ending),
                Event::Started { .. } => Some(Ending::Completed), // a marker for a start
                _ => None,
            })
            .collect()
    }

    #[test]
    fn recovery_drives_back_to_guard_and_cancel_stops_it_where_it_is() {
        let mut lifecycle = Lifecycle::<Policy>::default();
        let mut away = FakeWorld::new(1).read_slot(0);
        away.bodies[Body::ForearmR.index()].rotation = Quat::from_rotation_x(0.5);
        lifecycle.recover(rest_geometry());
        assert_eq!(lifecycle.begin_frame(&away), FrameNeeds::Nothing);
        assert!(matches!(lifecycle.act(None, CALM), Ok(Drive::Motors(commands)) if commands[2].length() > 1.0));
        lifecycle.begin_frame(&FakeWorld::new(1).read_slot(0));
        assert_eq!(
            (lifecycle.act(None, CALM).ok(), events(&mut lifecycle)),
            (Some(Drive::Hold), vec![Event::Recovered])
        );
        assert_eq!(lifecycle.act(None, CALM).ok(), Some(Drive::Nothing));
        lifecycle.recover(rest_geometry());
        lifecycle.cancel();
        assert_eq!(
            (lifecycle.act(None, CALM).ok(), events(&mut lifecycle)),
            (Some(Drive::Hold), vec![]),
            "no punch ran"
        );
        assert!(!lifecycle.is_active());
    }

    #[test]
    fn a_punch_away_from_guard_returns_to_guard_first() {
        let mut lifecycle = Lifecycle::<Policy>::default();
        let mut away = FakeWorld::new(1).read_slot(0);
        away.bodies[Body::ForearmR.index()].rotation = Quat::from_rotation_x(0.5);
        lifecycle.start(start(1, true), 1, CALM);
        assert_eq!(lifecycle.begin_frame(&away), FrameNeeds::Nothing, "guarding first");
        assert!(matches!(lifecycle.act(None, CALM), Ok(Drive::Motors(_))) && lifecycle.is_punching());
        assert_eq!(lifecycle.begin_frame(&FakeWorld::new(1).read_slot(0)), FrameNeeds::Target, "in guard: punching");
    }

    fn played_actions(lifecycle: &mut Lifecycle<Policy>, policy: Policy, noise: NoiseSettings) -> Vec<f32> {
        let mut world = FakeWorld::new(1);
        lifecycle.start(start(policy, false), policy as usize, noise);
        while lifecycle.is_punching() {
            frame(lifecycle, &mut world, noise, forward);
        }
        lifecycle.last_record().actions.clone()
    }

    #[test]
    fn punches_from_one_seed_differ_and_a_new_seed_or_policy_starts_a_new_sequence() {
        let noisy = NoiseSettings { seed: 4, sigma: 0.3, noisy_decisions: -1 };
        let mut lifecycle = Lifecycle::default();
        let first = played_actions(&mut lifecycle, 1, noisy);
        let second = played_actions(&mut lifecycle, 1, noisy);
        assert_ne!(first, second, "each punch differs");
        let mut other = Lifecycle::default();
        assert_eq!(played_actions(&mut other, 1, noisy), first, "the same seed replays the sequence");
        assert_eq!(played_actions(&mut lifecycle, 2, noisy), first, "a new policy starts the sequence again");
        assert_ne!(played_actions(&mut lifecycle, 2, NoiseSettings { seed: 5, ..noisy }), first);
    }

    /// What a game may do between frames, in any order.
    #[derive(Debug, Clone)]
    enum Call {
        Punch { policy: Policy, guard_first: bool },
        Cancel,
        Recover,
        Fail,
        Frames(usize),
        FailedInference,
    }

    fn call() -> impl Strategy<Value = Call> {
        prop_oneof![
            (0..3u8, any::<bool>()).prop_map(|(policy, guard_first)| Call::Punch { policy, guard_first }),
            Just(Call::Cancel),
            Just(Call::Recover),
            Just(Call::Fail),
            (1..70usize).prop_map(Call::Frames),
            Just(Call::FailedInference),
        ]
    }

    proptest! {
        #[test]
        fn every_start_is_followed_by_exactly_one_finish(calls in prop::collection::vec(call(), 1..25)) {
            let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
            let mut heard = Vec::new();
            for call in calls {
                match call {
                    Call::Punch { policy, guard_first } => lifecycle.start(start(policy, guard_first), policy as usize, CALM),
                    Call::Cancel => lifecycle.cancel(),
                    Call::Recover => lifecycle.recover(rest_geometry()),
                    Call::Fail => lifecycle.fail("the character was freed"),
                    Call::Frames(count) => {
                        for _ in 0..count {
                            frame(&mut lifecycle, &mut world, CALM, forward);
                        }
                    }
                    Call::FailedInference => {
                        frame(&mut lifecycle, &mut world, CALM, |_| Err(CoreError::Inference("failed".into())));
                    }
                }
                heard.extend(events(&mut lifecycle));
            }
            let mut open = false;
            for event in &heard {
                match event {
                    Event::Started { .. } => { prop_assert!(!open, "a start before the last punch finished: {heard:?}"); open = true }
                    Event::OutOfReach { .. } => prop_assert!(open, "out of reach outside a punch"),
                    Event::Finished(..) => { prop_assert!(open, "a finish with no punch: {heard:?}"); open = false }
                    Event::Hit(_) => prop_assert!(open, "a hit outside a punch"),
                    Event::Recovered => prop_assert!(!open, "recovered during a punch"),
                }
            }
            prop_assert_eq!(open, lifecycle.is_punching());
            // However it got here, a game that lets frames run hears the end.
            for _ in 0..200 { frame(&mut lifecycle, &mut world, CALM, forward); }
            let finishes = events(&mut lifecycle).iter().filter(|e| matches!(e, Event::Finished(..))).count();
            prop_assert!(!lifecycle.is_active(), "done, and nothing left to say");
            prop_assert_eq!(finishes, usize::from(open));
        }
    }
}
