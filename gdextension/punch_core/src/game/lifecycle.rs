//! What a game's punch controller does with its character, free of Godot: the phases (idle, returning to
//! guard before a punch, punching, recovering), the runtime noise that makes each punch differ, and the
//! events the game hears of, in the order they happened.
//!
//! The promise kept here: every `Event::Started` is followed by exactly one `Event::Finished`, however the
//! punch ends (its last frame, a new punch, `cancel`, an error, the controller leaving the game).
//!
//! Combos: a move asked for while a punch runs waits in a queue (`enqueue`) for the running punch's cancel window,
//! which opens a designer's delay after the punching fist first lands (or after the punch's last frame, when it
//! lands nothing); then the running punch ends (`Ending::Chained`) and the queued one starts from where the arms
//! are. A punch and those chained from it are a string: each punch's `Started` carries its index in it, and
//! one `Event::ComboFinished` follows the string's last `Finished`.
//!
//! The Godot layer (`PunchController`) reads the engine into `FrameReading`s and `Touch`es, drives the joints
//! with the commands it gets back, and turns each event into a signal, one at a time (`next_event`), so that a
//! signal handler that starts another punch hears of the first one's end before the second one's start.

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
    /// A punch began: the hand that throws it, the move it is (None: a policy played as it is) and its index in
    /// its string of chained punches (0: started on its own).
    Started { hand: Hand, punch_move: Option<Move>, combo_index: u32 },
    /// The punch just started goes at the nearest point the policy covers: the target was outside its reach
    /// volume. The target's offset in the character's frame, and that point (world coordinates).
    OutOfReach { offset: Vec3, nearest: Vec3 },
    /// A fist struck something for the first time in this punch.
    Hit(Hit),
    /// The punch is over.
    Finished(PunchSummary, Ending),
    /// The character is back in its guard pose (or the recovery's time is up).
    Recovered,
    /// A string of punches is over (it follows its last punch's `Finished`): how many of its punches landed
    /// (the punching fist struck something) and how many were thrown.
    ComboFinished { landed: u32, thrown: u32 },
}

/// How a punch ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// It played its last frame.
    Completed,
    /// It was ended early: cancelled, replaced by another punch, or its controller left the game.
    Interrupted,
    /// It was ended at its cancel window, for the punch queued after it.
    Chained,
    /// The character was struck while it punched (`struck`): the punch gave way to the hit.
    Struck,
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
    /// Return to guard first (the character is away from it: the end of an earlier punch, mid-recovery) until every
    /// joint is within this angle of its guard angle (rad; `Recovery::ready_to_punch`); None: from where the arms are.
    pub guard_first: Option<f32>,
    /// Where the punch starts with `guard_first` (joint targets, rad, action order): its move's load
    /// (`stance::Load`), drawn there even from the guard; None: the guard.
    pub start_pose: Option<[f32; DOF_COUNT]>,
    pub out_of_reach: Option<(Vec3, Vec3)>,
    /// Physics frames from the punching fist's first contact (or the punch's last frame) to its cancel window,
    /// when a punch queued after it starts.
    pub cancel_delay_frames: u32,
}

/// The string of chained punches that runs.
#[derive(Debug, Clone, Copy, Default)]
struct Tally {
    /// The running (or last) punch's index in the string.
    index: u32,
    /// Punches of the string that landed, the running one not yet counted.
    landed: u32,
    /// The running punch's fist has landed.
    running_landed: bool,
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
    /// The running recovery says `Recovered` when it is there (false: a quiet `settle` into a new guard).
    announce_recovery: bool,
    /// While a block holds its guard (the running recovery): the quiet way back to `guard` when it ends.
    after_block: Option<Box<Recovery>>,
    /// Moves asked for while a punch ran, oldest first, by the caller's names: the caller builds each one's
    /// `PunchStart` when it is due (`due`, `chain`).
    queued: VecDeque<String>,
    /// Physics frames until the running (or last) punch's cancel window opens; None while it has not landed.
    window_in: Option<u32>,
    /// The running punch's `PunchStart::cancel_delay_frames`.
    cancel_delay_frames: u32,
    /// The string of punches running, if one is.
    string: Option<Tally>,
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
            announce_recovery: true,
            after_block: None,
            queued: VecDeque::new(),
            window_in: None,
            cancel_delay_frames: 0,
            string: None,
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
        !matches!(self.phase, Phase::Idle) || self.hold_next || !self.events.is_empty() || !self.queued.is_empty()
    }

    /// True while a move asked for now waits (`enqueue`) rather than starting at once: a punch runs, or moves
    /// wait for its cancel window.
    pub fn is_busy(&self) -> bool {
        self.is_punching() || !self.queued.is_empty()
    }

    /// The moves waiting for the running punch's cancel window, oldest first.
    pub fn queued(&self) -> impl Iterator<Item = &str> {
        self.queued.iter().map(String::as_str)
    }

    /// Queues `moves` (the caller's names) after the running punch, replacing what waited: the first starts at
    /// the running punch's cancel window, each later one at the one before's (`due`, `chain`).
    pub fn enqueue(&mut self, moves: impl IntoIterator<Item = String>) {
        self.queued = moves.into_iter().collect();
    }

    /// The queued move due now (its predecessor's cancel window is open): the caller builds its `PunchStart` and
    /// calls `chain`, before `begin_frame`, or `drop_due` when it cannot be thrown.
    pub fn due(&self) -> Option<&str> {
        let open = self.window_in == Some(0) && !matches!(self.phase, Phase::Guarding(..));
        self.queued.front().map(String::as_str).filter(|_| open)
    }

    /// Drops the queued move due now (it could not be thrown: the caller reported why); the next one, if any, is
    /// due at once. The string ends when nothing runs or waits.
    pub fn drop_due(&mut self) {
        self.queued.pop_front();
        if self.queued.is_empty() && !self.is_punching() {
            self.end_string();
        }
    }

    /// Starts the queued move due now (`due`): the running punch ends (`Ending::Chained`), and `start` plays on
    /// from where the arms are (or returns to guard first) as the next punch of the string.
    pub fn chain(&mut self, start: PunchStart<P>, identity: usize, noise: NoiseSettings) {
        self.end_punch(Ending::Chained);
        self.queued.pop_front();
        let index = self.string.map_or(0, |tally| tally.index + 1);
        self.begin(start, identity, noise, index);
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

    /// Starts a punch now, on its own: one that is running ends first (interrupted), and what was queued is
    /// dropped. `identity` tells policies apart for the noise: a new seed or a new policy starts a new sequence
    /// of punches.
    pub fn start(&mut self, start: PunchStart<P>, identity: usize, noise: NoiseSettings) {
        self.after_block = None;
        self.queued.clear();
        self.interrupt();
        self.end_string();
        self.begin(start, identity, noise, 0);
    }

    /// Starts `start` as punch `combo_index` of the string (0: a new string).
    fn begin(&mut self, start: PunchStart<P>, identity: usize, noise: NoiseSettings, combo_index: u32) {
        if self.noise_key != Some((noise.seed, identity)) {
            self.noise = RuntimeNoise::new(noise.seed as u64, noise.sigma, noise.noisy_decisions);
            self.noise_key = Some((noise.seed, identity));
        }
        let punch = Box::new(start.punch);
        let (hand, punch_move) = (punch.hand(), punch.punch_move());
        let geometry = *punch.geometry();
        self.phase = match start.guard_first {
            // Decided at the next frame's reading: a character already in guard punches in that same frame.
            Some(angle_rad) => {
                let recovery =
                    Recovery::new(geometry, start.start_pose.unwrap_or(self.guard)).ready_to_punch(angle_rad);
                Phase::Guarding(punch, start.policy, Box::new(recovery), [Vec3::ZERO; 5])
            }
            None => Phase::Punching(punch, start.policy),
        };
        self.hold_next = false;
        self.window_in = None;
        self.cancel_delay_frames = start.cancel_delay_frames;
        self.string = Some(Tally { index: combo_index, running_landed: false, ..self.string.unwrap_or_default() });
        self.events.push_back(Event::Started { hand, punch_move, combo_index });
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
        self.queued.clear();
        if self.end_punch(Ending::Error(error.to_string())) {
            self.noise_key = None;
        } else if self.is_recovering() {
            self.phase = Phase::Idle;
            self.hold_next = true;
        }
        self.end_string();
    }

    /// Ends the punch or recovery that is running; the joints then hold the pose they are in.
    pub fn cancel(&mut self) {
        self.after_block = None;
        self.queued.clear();
        self.interrupt();
        self.end_string();
        if matches!(std::mem::replace(&mut self.phase, Phase::Idle), Phase::Recovering(..)) {
            self.hold_next = true;
        }
    }

    /// Drives the character back to its guard pose (ending a punch that is running); `Recovered` comes
    /// when it is there.
    pub fn recover(&mut self, geometry: CharacterGeometry) {
        self.back_to_guard(Recovery::new(geometry, self.guard), Ending::Interrupted);
    }

    /// Drives an idle character into its guard pose without a word (no `Recovered`): a character that has just
    /// been given a new guard (a stance) stands in it before it is asked for anything. Does nothing while a punch or
    /// recovery runs: that one ends in the new guard anyway.
    pub fn settle(&mut self, geometry: CharacterGeometry) {
        if self.is_active() {
            return;
        }
        self.back_to_guard(Recovery::new(geometry, self.guard), Ending::Interrupted);
        self.announce_recovery = false;
    }

    /// Blocks: ends what runs (a punch, interrupted; what was queued is dropped) and drives the character into
    /// `block_guard`, holding it there for `frames` physics frames (None: until `lower_block`, a punch, a recovery
    /// or `cancel`), then quietly back into its guard. Says nothing itself (no `Recovered`).
    pub fn block(&mut self, geometry: CharacterGeometry, block_guard: [f32; DOF_COUNT], frames: Option<u32>) {
        self.back_to_guard(
            Recovery::new(geometry, block_guard).holding(frames.unwrap_or(u32::MAX)),
            Ending::Interrupted,
        );
        self.announce_recovery = false;
        self.after_block = Some(Box::new(Recovery::new(geometry, self.guard)));
    }

    /// While a block holds its guard, drives it to `block_guard` from now on (the trunk turning to follow the
    /// opponent); its time runs on. Nothing happens if none holds.
    pub fn turn_block(&mut self, block_guard: [f32; DOF_COUNT]) {
        if self.after_block.is_some()
            && let Phase::Recovering(holding, _) = &mut self.phase
        {
            holding.retarget(block_guard);
        }
    }

    /// True while a block holds its guard.
    pub fn is_blocking(&self) -> bool {
        self.after_block.is_some()
    }

    /// Ends a block now: the character goes quietly back into its guard. Nothing happens if none holds.
    pub fn lower_block(&mut self) {
        if let Some(back) = self.after_block.take() {
            self.phase = Phase::Recovering(back, [Vec3::ZERO; 5]);
            self.hold_next = false;
            self.announce_recovery = false;
        }
    }

    /// The character was struck: a running punch ends (`Ending::Struck`; what was queued is dropped) unless it has
    /// `armoured` (a designer's hyper-armour: it plays on, and nothing else changes), and the body, given way to the
    /// hit, is driven back to its guard (`Recovered` when there), from wherever the hit left it. Returns whether a
    /// punch was ended.
    pub fn struck(&mut self, geometry: CharacterGeometry, armoured: bool) -> bool {
        if self.is_punching() && armoured {
            return false;
        }
        let was_punching = self.is_punching();
        self.back_to_guard(Recovery::new(geometry, self.guard).after_hit(), Ending::Struck);
        was_punching
    }

    /// Ends what runs (a punch with `ending`) and drives the character back to its guard with `recovery`.
    fn back_to_guard(&mut self, recovery: Recovery, ending: Ending) {
        self.queued.clear();
        self.end_punch(ending);
        self.end_string();
        self.phase = Phase::Recovering(Box::new(recovery), [Vec3::ZERO; 5]);
        self.hold_next = false;
        self.announce_recovery = true;
        self.after_block = None;
    }

    /// First half of a physics frame: the character's bodies were just read into `reading`. Steps a
    /// return to guard; says whether a punch plays this frame (the caller then reads the target and calls
    /// `sense`).
    pub fn begin_frame(&mut self, reading: &FrameReading) -> FrameNeeds {
        if let Some(frames) = &mut self.window_in {
            *frames = frames.saturating_sub(1);
        }
        match &mut self.phase {
            Phase::Idle => FrameNeeds::Nothing,
            Phase::Recovering(recovery, commands) => {
                match recovery.step(reading) {
                    Some(next) => *commands = next,
                    None => match self.after_block.take() {
                        // A block's time is up: back to the guard, as quietly.
                        Some(back) => self.phase = Phase::Recovering(back, *commands),
                        None => {
                            self.phase = Phase::Idle;
                            self.hold_next = true;
                            if self.announce_recovery {
                                self.events.push_back(Event::Recovered);
                            }
                        }
                    },
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
        if hits.iter().any(|hit| hit.hand == punch.hand()) {
            // The punching fist landed: the cancel window opens the designer's delay from now.
            self.window_in.get_or_insert(self.cancel_delay_frames);
            if let Some(tally) = &mut self.string {
                tally.running_landed = true;
            }
        }
        self.events.extend(hits.into_iter().map(Event::Hit));
        match sensed {
            Sensed::Hold => None,
            Sensed::Decide(observation) => Some((policy.clone(), observation)),
            Sensed::Finished(summary, record) => {
                self.events.push_back(Event::Finished(summary, Ending::Completed));
                self.window_in.get_or_insert(self.cancel_delay_frames);
                self.count_finished_punch(true);
                self.last_record = record.unwrap_or_default();
                self.phase = Phase::Idle;
                self.hold_next = true;
                if let Some(geometry) = recover_at() {
                    let mut recovery = Recovery::new(geometry, self.guard);
                    if let Some(commands) = recovery.step(&reading) {
                        self.phase = Phase::Recovering(Box::new(recovery), commands);
                        self.hold_next = false;
                        self.announce_recovery = true;
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
        let chained = ending == Ending::Chained;
        self.events.push_back(Event::Finished(summary, ending));
        self.count_finished_punch(chained);
        self.hold_next = true;
        true
    }

    /// Counts the punch that just finished in its string; the string ends with it unless `goes_on` and a move
    /// waits to chain.
    fn count_finished_punch(&mut self, goes_on: bool) {
        if let Some(tally) = &mut self.string {
            tally.landed += u32::from(std::mem::take(&mut tally.running_landed));
        }
        if !goes_on || self.queued.is_empty() {
            self.queued.clear();
            self.end_string();
        }
    }

    /// Ends the running string of punches (`ComboFinished`), if there is one.
    fn end_string(&mut self) {
        if let Some(tally) = self.string.take() {
            self.events.push_back(Event::ComboFinished { landed: tally.landed, thrown: tally.index + 1 });
        }
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
        PunchStart {
            punch: Punch::new(rest_geometry(), spec, true),
            policy,
            guard_first: guard_first.then_some(Recovery::READY_ANGLE_RAD),
            start_pose: None,
            out_of_reach: None,
            cancel_delay_frames: 0,
        }
    }

    /// One physics frame of the fake world as `PunchController` plays it; returns the policy asked (if a
    /// decision was due) and what was driven. `decide` plays the policy (an error ends the punch).
    fn frame(
        lifecycle: &mut Lifecycle<Policy>,
        world: &mut FakeWorld,
        noise: NoiseSettings,
        decide: impl FnOnce(Policy) -> Result<Vec<f32>, CoreError>,
    ) -> (Option<Policy>, Drive) {
        if let Some(policy) = lifecycle.due().map(|name| name.parse::<Policy>().expect("a policy number")) {
            lifecycle.chain(start(policy, false), policy as usize, noise);
        }
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
        assert_eq!(events[0], Event::Started { hand: Hand::Right, punch_move: None, combo_index: 0 });
        assert!(matches!(events[1], Event::Hit(hit) if hit.collider == FAKE_BAG_ID));
        let Event::Finished(summary, Ending::Completed) = &events[2] else { panic!("{events:?}") };
        assert_eq!((summary.frames, summary.hits, events.len()), (50, 1, 4));
        assert_eq!(events[3], Event::ComboFinished { landed: 1, thrown: 1 }, "a punch on its own is a string of one");
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
            matches!(&ends[..], [Event::Started { .. }, Event::Finished(summary, Ending::Interrupted),
                Event::ComboFinished { thrown: 1, .. }, Event::Started { combo_index: 0, .. }]
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
    fn settling_into_a_new_guard_says_nothing_and_waits_for_what_runs() {
        let mut lifecycle = Lifecycle::<Policy>::default();
        let mut away = FakeWorld::new(1).read_slot(0);
        away.bodies[Body::ForearmR.index()].rotation = Quat::from_rotation_x(0.5);
        lifecycle.settle(rest_geometry());
        assert!(lifecycle.is_recovering(), "an idle character is driven into its guard");
        lifecycle.begin_frame(&away);
        assert!(matches!(lifecycle.act(None, CALM), Ok(Drive::Motors(commands)) if commands[2].length() > 1.0));
        lifecycle.begin_frame(&FakeWorld::new(1).read_slot(0));
        assert_eq!(
            (lifecycle.act(None, CALM).ok(), events(&mut lifecycle)),
            (Some(Drive::Hold), vec![]),
            "no Recovered"
        );
        // A recovery asked for afterwards still says when it is there.
        lifecycle.recover(rest_geometry());
        lifecycle.begin_frame(&FakeWorld::new(1).read_slot(0));
        assert_eq!(events(&mut lifecycle), vec![Event::Recovered]);
        // While a punch runs, settling changes nothing: the punch ends in the new guard anyway.
        let mut world = FakeWorld::new(1);
        lifecycle.start(start(1, false), 1, CALM);
        lifecycle.settle(rest_geometry());
        assert!(lifecycle.is_punching());
        frame(&mut lifecycle, &mut world, CALM, forward);
        assert!(matches!(events(&mut lifecycle)[..], [Event::Started { .. }]));
    }

    #[test]
    fn a_turned_block_drives_to_its_new_guard_for_the_rest_of_its_time_and_nothing_else_turns() {
        let world = FakeWorld::new(1);
        let commands = |lifecycle: &mut Lifecycle<Policy>| {
            lifecycle.begin_frame(&world.read_slot(0));
            lifecycle.act(None, CALM).ok()
        };
        let (mut turned, mut held) = (Lifecycle::<Policy>::default(), Lifecycle::<Policy>::default());
        turned.block(rest_geometry(), [0.5; DOF_COUNT], Some(3));
        held.block(rest_geometry(), [0.5; DOF_COUNT], Some(3));
        assert!(matches!(commands(&mut turned), Some(Drive::Motors(_))));
        commands(&mut held);
        turned.turn_block([-0.5; DOF_COUNT]);
        assert_ne!(commands(&mut turned), commands(&mut held), "driven toward the new guard");
        commands(&mut turned);
        commands(&mut held);
        turned.begin_frame(&world.read_slot(0));
        assert!(!turned.is_blocking(), "its time ran on: three frames in all");
        // Outside a block (on the way back to guard, or idle) nothing turns.
        let (mut back, mut twin) = (Lifecycle::<Policy>::default(), Lifecycle::<Policy>::default());
        for lifecycle in [&mut back, &mut twin] {
            lifecycle.block(rest_geometry(), [0.5; DOF_COUNT], None);
            lifecycle.lower_block();
        }
        back.turn_block([-0.5; DOF_COUNT]);
        assert_eq!(commands(&mut back), commands(&mut twin));
        Lifecycle::<Policy>::default().turn_block([-0.5; DOF_COUNT]);
    }

    #[test]
    fn a_block_ends_the_punch_holds_its_guard_for_its_time_then_goes_back_quietly() {
        let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
        lifecycle.start(start(1, false), 1, CALM);
        lifecycle.enqueue(["2".to_string()]);
        frame(&mut lifecycle, &mut world, CALM, forward);
        let high = [0.5; DOF_COUNT];
        lifecycle.block(rest_geometry(), high, Some(3));
        assert!(lifecycle.is_blocking() && !lifecycle.is_punching() && lifecycle.queued().count() == 0);
        let heard = events(&mut lifecycle);
        assert!(
            matches!(
                heard[..],
                [
                    Event::Started { .. },
                    Event::Finished(_, Ending::Interrupted),
                    Event::ComboFinished { thrown: 1, .. }
                ]
            ),
            "{heard:?}"
        );
        // Held for its three frames even once there (the fake world's joints never move), then back to guard.
        for _ in 0..3 {
            lifecycle.begin_frame(&world.read_slot(0));
            assert!(lifecycle.is_blocking() && lifecycle.is_recovering());
            assert!(matches!(lifecycle.act(None, CALM), Ok(Drive::Motors(_))));
        }
        lifecycle.begin_frame(&world.read_slot(0));
        assert!(!lifecycle.is_blocking() && lifecycle.is_recovering(), "on its way back to guard");
        lifecycle.act(None, CALM).expect("drives");
        lifecycle.begin_frame(&world.read_slot(0));
        assert_eq!((lifecycle.act(None, CALM).ok(), events(&mut lifecycle)), (Some(Drive::Hold), vec![]), "quietly");
        // Held until lowered; a punch or a cancel ends it too.
        lifecycle.block(rest_geometry(), high, None);
        for _ in 0..500 {
            lifecycle.begin_frame(&world.read_slot(0));
            lifecycle.act(None, CALM).expect("drives");
        }
        assert!(lifecycle.is_blocking());
        lifecycle.lower_block();
        assert!(!lifecycle.is_blocking() && lifecycle.is_recovering());
        lifecycle.block(rest_geometry(), high, None);
        lifecycle.start(start(1, false), 1, CALM);
        assert!(!lifecycle.is_blocking() && lifecycle.is_punching());
        lifecycle.block(rest_geometry(), high, None);
        lifecycle.cancel();
        assert!(!lifecycle.is_blocking() && !lifecycle.is_recovering());
    }

    #[test]
    fn a_struck_punch_gives_way_and_returns_to_guard_unless_it_has_armour() {
        let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
        lifecycle.start(start(1, false), 1, CALM);
        lifecycle.enqueue(["2".to_string()]);
        frame(&mut lifecycle, &mut world, CALM, forward);
        assert!(!lifecycle.struck(rest_geometry(), true), "hyper-armour: the punch plays on");
        assert!(lifecycle.is_punching() && lifecycle.queued().count() == 1);
        assert!(lifecycle.struck(rest_geometry(), false));
        assert!(!lifecycle.is_punching() && lifecycle.is_recovering() && lifecycle.queued().count() == 0);
        let heard = events(&mut lifecycle);
        assert!(
            matches!(
                heard[..],
                [Event::Started { .. }, Event::Finished(_, Ending::Struck), Event::ComboFinished { thrown: 1, .. }]
            ),
            "{heard:?}"
        );
        // Struck standing: no punch to end, back to guard all the same.
        lifecycle.cancel();
        assert!(!lifecycle.struck(rest_geometry(), false) && lifecycle.is_recovering());
        for _ in 0..200 {
            frame(&mut lifecycle, &mut world, CALM, forward);
        }
        assert_eq!(events(&mut lifecycle), vec![Event::Recovered]);
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

    #[test]
    fn a_punch_from_a_load_draws_the_arm_there_first_even_from_the_guard() {
        let in_guard = FakeWorld::new(1).read_slot(0);
        let mut lifecycle = Lifecycle::<Policy>::default();
        let loaded = crate::contract::stance::Load::Hook.loaded([0.0; DOF_COUNT]);
        lifecycle.start(PunchStart { start_pose: Some(loaded), ..start(1, true) }, 1, CALM);
        assert_eq!(lifecycle.begin_frame(&in_guard), FrameNeeds::Nothing, "loading first");
        assert!(matches!(lifecycle.act(None, CALM), Ok(Drive::Motors(_))) && lifecycle.is_punching());
        // A start pose that is the guard itself starts at once, as the guard does.
        let mut lifecycle = Lifecycle::<Policy>::default();
        lifecycle.start(PunchStart { start_pose: Some([0.0; DOF_COUNT]), ..start(1, true) }, 1, CALM);
        assert_eq!(lifecycle.begin_frame(&in_guard), FrameNeeds::Target, "in its start pose: punching");
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

    #[test]
    fn a_queued_punch_starts_at_the_running_ones_contact_plus_its_delay_and_the_string_ends_once() {
        for delay in [0u32, 7] {
            let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
            lifecycle.start(PunchStart { cancel_delay_frames: delay, ..start(1, false) }, 1, CALM);
            lifecycle.enqueue(["2".to_string(), "2".to_string()]);
            assert!(lifecycle.is_busy());
            let mut heard = Vec::new();
            let mut first_hit_at = None;
            let mut second_started_at = None;
            for index in 0..200 {
                frame(&mut lifecycle, &mut world, CALM, forward);
                for event in events(&mut lifecycle) {
                    match event {
                        Event::Hit(_) if first_hit_at.is_none() => first_hit_at = Some(index),
                        Event::Started { combo_index: 1, .. } => second_started_at = Some(index),
                        _ => {}
                    }
                    heard.push(event);
                }
            }
            let (hit, started) = (first_hit_at.expect("the first punch lands"), second_started_at.expect("chained"));
            // The hit is sensed in frame `hit`; the window opens `delay` frames on, the next punch one frame later.
            assert_eq!(started, hit + delay as usize + 1, "delay {delay}");
            let kinds: Vec<_> = heard
                .iter()
                .filter_map(|event| match event {
                    Event::Started { combo_index, .. } => Some(format!("S{combo_index}")),
                    Event::Finished(_, ending) => Some(format!("F:{ending:?}")),
                    Event::ComboFinished { landed, thrown } => Some(format!("C{landed}/{thrown}")),
                    _ => None,
                })
                .collect();
            assert_eq!(kinds, ["S0", "F:Chained", "S1", "F:Chained", "S2", "F:Completed", "C3/3"], "delay {delay}");
            assert!(!lifecycle.is_active());
        }
    }

    #[test]
    fn a_punch_that_lands_nothing_opens_its_window_at_its_last_frame() {
        let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
        let away = |_| Ok(vec![0.0; 10]); // the guard held: the bag is never touched
        lifecycle.start(start(1, false), 1, CALM);
        lifecycle.enqueue(["2".to_string()]);
        let mut last_frame_of_first = None;
        for index in 0..60 {
            frame(&mut lifecycle, &mut world, CALM, away);
            if last_frame_of_first.is_none()
                && events(&mut lifecycle).iter().any(|e| matches!(e, Event::Finished(_, Ending::Completed)))
            {
                last_frame_of_first = Some(index);
                assert!(lifecycle.is_busy() && lifecycle.due() == Some("2"), "due at the next frame");
            }
        }
        assert_eq!(last_frame_of_first, Some(50));
        let heard = events(&mut lifecycle);
        assert!(matches!(heard[0], Event::Started { combo_index: 1, .. }), "{heard:?}");
    }

    /// What a game may do between frames, in any order.
    #[derive(Debug, Clone)]
    enum Call {
        /// `start`: a punch now, on its own (what was queued is dropped).
        Punch {
            policy: Policy,
            guard_first: bool,
        },
        /// What `PunchController.punch`/`combo` do: queue the moves while busy, else start the first now.
        Ask(Vec<Policy>),
        Cancel,
        Recover,
        Fail,
        /// `PunchController.block`: for some frames, or until lowered.
        Block(Option<u32>),
        LowerBlock,
        /// A new stance or `stance_pose` set while idle.
        Settle,
        /// Another's fist (or the game's `take_hit`) struck the character, with or without hyper-armour.
        Struck(bool),
        Frames(usize),
        FailedInference,
    }

    fn call() -> impl Strategy<Value = Call> {
        prop_oneof![
            (0..3u8, any::<bool>()).prop_map(|(policy, guard_first)| Call::Punch { policy, guard_first }),
            prop::collection::vec(0..3u8, 1..5).prop_map(Call::Ask),
            prop::collection::vec(0..3u8, 1..5).prop_map(Call::Ask),
            Just(Call::Cancel),
            Just(Call::Recover),
            Just(Call::Fail),
            prop::option::of(1..90u32).prop_map(Call::Block),
            Just(Call::LowerBlock),
            Just(Call::Settle),
            any::<bool>().prop_map(Call::Struck),
            (1..70usize).prop_map(Call::Frames),
            Just(Call::FailedInference),
        ]
    }

    /// What the game has heard, checked as it hears it: one finish per start, one `ComboFinished` per string after
    /// its last finish, and each queued move started once, in order, unless dropped.
    #[derive(Debug, Default)]
    struct Listener {
        punch_open: bool,
        /// The open string's last punch index.
        string: Option<u32>,
        /// The moves the game queued and has not seen start or dropped.
        waiting: VecDeque<Policy>,
        /// The last punch ended chained: the next event must be its successor's start.
        chained: bool,
    }

    impl Listener {
        fn hear(&mut self, event: &Event) -> Result<(), TestCaseError> {
            prop_assert!(
                !self.chained || matches!(event, Event::Started { .. }),
                "a chained punch's end, then {event:?}"
            );
            match event {
                Event::Started { combo_index, .. } => {
                    prop_assert!(!self.punch_open, "a start before the last punch finished");
                    self.punch_open = true;
                    self.chained = false;
                    match (*combo_index, self.string) {
                        (0, None) => self.string = Some(0),
                        (index, Some(last)) if index == last + 1 => {
                            prop_assert!(self.waiting.pop_front().is_some(), "a chained start nobody queued");
                            self.string = Some(index);
                        }
                        other => prop_assert!(false, "start {other:?} out of its string"),
                    }
                }
                Event::OutOfReach { .. } | Event::Hit(_) => prop_assert!(self.punch_open, "{event:?} outside a punch"),
                Event::Finished(_, ending) => {
                    prop_assert!(self.punch_open, "a finish with no punch");
                    self.punch_open = false;
                    self.chained = *ending == Ending::Chained;
                    if matches!(ending, Ending::Interrupted | Ending::Error(_) | Ending::Struck) {
                        self.waiting.clear();
                    }
                }
                Event::Recovered => prop_assert!(!self.punch_open, "recovered during a punch"),
                Event::ComboFinished { landed, thrown } => {
                    prop_assert!(!self.punch_open, "a string ended during a punch");
                    prop_assert_eq!(Some(*thrown), self.string.map(|last| last + 1));
                    prop_assert!(landed <= thrown);
                    prop_assert!(self.waiting.is_empty(), "a string ended with moves waiting: {:?}", self.waiting);
                    self.string = None;
                }
            }
            Ok(())
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(10_000))]
        #[test]
        fn every_start_has_one_finish_every_string_one_end_and_no_queued_move_is_lost_or_doubled(
            calls in prop::collection::vec(call(), 1..25)
        ) {
            let (mut lifecycle, mut world) = (Lifecycle::default(), FakeWorld::new(1));
            let mut listener = Listener::default();
            for call in calls {
                match call {
                    Call::Punch { policy, guard_first } => {
                        listener.waiting.clear();
                        lifecycle.start(start(policy, guard_first), policy as usize, CALM)
                    }
                    Call::Ask(moves) => {
                        let mut moves: VecDeque<_> = moves.into();
                        if !lifecycle.is_busy() {
                            let first = moves.pop_front().expect("one move at least");
                            listener.waiting.clear();
                            lifecycle.start(start(first, false), first as usize, CALM);
                        }
                        lifecycle.enqueue(moves.iter().map(u8::to_string));
                        listener.waiting = moves;
                    }
                    Call::Cancel | Call::Recover | Call::Fail => {
                        listener.waiting.clear();
                        match call {
                            Call::Cancel => lifecycle.cancel(),
                            Call::Recover => lifecycle.recover(rest_geometry()),
                            _ => lifecycle.fail("the character was freed"),
                        }
                    }
                    Call::Block(frames) => {
                        listener.waiting.clear();
                        lifecycle.block(rest_geometry(), [0.3; DOF_COUNT], frames);
                        prop_assert!(lifecycle.is_blocking() && !lifecycle.is_punching());
                    }
                    Call::LowerBlock => lifecycle.lower_block(),
                    Call::Settle => lifecycle.settle(rest_geometry()),
                    Call::Struck(armoured) => {
                        let punching = lifecycle.is_punching();
                        let ended = lifecycle.struck(rest_geometry(), armoured);
                        prop_assert_eq!(ended, punching && !armoured);
                        if !(punching && armoured) {
                            listener.waiting.clear();
                            prop_assert!(lifecycle.is_recovering(), "struck, and not driven back to guard");
                        }
                    }
                    Call::Frames(count) => {
                        for _ in 0..count {
                            frame(&mut lifecycle, &mut world, CALM, forward);
                            for event in events(&mut lifecycle) { listener.hear(&event)?; }
                        }
                    }
                    Call::FailedInference => {
                        frame(&mut lifecycle, &mut world, CALM, |_| Err(CoreError::Inference("failed".into())));
                    }
                }
                for event in events(&mut lifecycle) { listener.hear(&event)?; }
                prop_assert_eq!(listener.punch_open, lifecycle.is_punching());
                let queued: Vec<String> = lifecycle.queued().map(str::to_string).collect();
                let expected: Vec<String> = listener.waiting.iter().map(u8::to_string).collect();
                prop_assert_eq!(queued, expected);
            }
            // However it got here, a game that lets frames run (and lowers a block it holds) hears every queued move
            // start, and the end.
            lifecycle.lower_block();
            for _ in 0..1000 {
                frame(&mut lifecycle, &mut world, CALM, forward);
                for event in events(&mut lifecycle) { listener.hear(&event)?; }
            }
            prop_assert!(!lifecycle.is_active(), "done, and nothing left to say");
            prop_assert!(!listener.punch_open && listener.string.is_none() && listener.waiting.is_empty(), "{listener:?}");
        }
    }
}
