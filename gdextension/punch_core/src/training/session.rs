//! The training server's logic, free of Godot: it answers protocol messages and runs episodes over a
//! `World` (the Godot layer implements it with real Jolt bodies). Messages and fields: docs/protocol.md.

use glam::Vec3;
use serde_json::{Value, json};

use crate::contract::character::{DOF_COUNT, PHYSICS_HZ};
use crate::contract::controller::CharacterController;
use crate::contract::motion::{self, RootPose};
use crate::contract::observation::{OBS_DIM, observation};
use crate::contract::sensing::{CharacterGeometry, FEATURE_COUNT, FrameReading, guard};
use crate::contract::spec::EpisodeConditions;
use crate::contract::spec::{DEFAULT_FRAMES, PolicySpec, handshake_fields};
use crate::training::protocol::{Array, Message, PROTOCOL_VERSION, error_reply};

/// The physics the session drives: N character slots, each with its own bag, never touching each other.
/// The Godot layer's `TrainingWorld` is the real one; the unit tests use a fake one.
pub trait World {
    fn slot_count(&self) -> usize;
    /// Rebuilds every slot in its initial state (a fresh physics world, so every reset is identical).
    fn reset(&mut self, placements: &[EpisodeConditions]) -> Result<(), String>;
    /// Puts a slot's bag back as `placement` hangs it (position, at rest or swinging as it says).
    fn place_bag(&mut self, slot: usize, placement: &EpisodeConditions);
    fn geometry(&self, slot: usize) -> CharacterGeometry;
    fn read(&self, slot: usize) -> FrameReading;
    /// Sets the joint motors of a slot for the next physics step.
    fn drive(&mut self, slot: usize, motor_velocities: &[Vec3; 5]);
    /// Moves a slot's kinematic pelvis so that its root is at `root` (the slot's frame at the episode's
    /// start) after the next physics step, moving at `root`'s velocities.
    fn move_pelvis(&mut self, slot: usize, root: &RootPose);
    /// Adds the motion of a root moving as `root` to every moving body of a slot's character (each as if
    /// carried rigidly by it), and to its bag when `with_bag` (a bag that rides along): an episode that starts
    /// while walking starts with the body already walking.
    fn carry_bodies(&mut self, slot: usize, root: &RootPose, with_bag: bool);
    /// Moves the top of a carried bag's rope (`EpisodeConditions::glides` or `rides`) to where `carry` (a rigid
    /// motion in the slot's frame at the episode's start) takes it from where the placement put it, reached
    /// after the next physics step; nothing for a bag on a fixed rope.
    fn move_rope(&mut self, slot: usize, carry: &RootPose);
}

/// What the engine layer does after handing a message to the session.
#[derive(Debug)]
pub enum Outcome {
    /// Send this reply now, then wait for the next message.
    Reply(Message),
    /// Let physics run; call `physics_frame` every frame until it returns a reply.
    Running,
    /// Send this reply and close the connection.
    Close(Message),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Command {
    Step,
    Rollout,
    /// A reset's lead-in: open-loop actions before the episode starts, not recorded; the episode of this
    /// spec starts from wherever they leave each character.
    LeadIn(PolicySpec),
}

#[derive(Debug)]
struct Run {
    command: Command,
    frames_total: usize,
    frames_done: usize,
    /// Open-loop actions [slot][decision][dof] (rollout and lead-in).
    actions: Vec<f32>,
    decisions: usize,
    features: Vec<f32>,
    /// Actions as executed after smoothing, [slot][decision][dof].
    executed: Vec<f32>,
}

/// Episode state shared by all slots (they always run in lockstep).
pub struct Session {
    slots: Vec<CharacterController>,
    decision_period: usize,
    frames_per_episode: usize,
    frame_index: usize,
    last_features: Vec<[f32; FEATURE_COUNT]>,
    broken: Vec<bool>,
    run: Option<Run>,
    episode_started: bool,
    /// Where each slot's bag hangs in the episode being reset (a lead-in's punch moves it; it is put back).
    placements: Vec<EpisodeConditions>,
    /// A rollout's open-loop actions and decisions, waiting for its lead-in to end.
    pending_rollout: Option<(Vec<f32>, usize)>,
}

/// Longest lead-in of a reset, decisions.
pub const MAX_LEAD_IN_DECISIONS: usize = 200;

/// The guard flags are the last feature (a sensing test checks it).
const FLAGS: usize = FEATURE_COUNT - 1;

impl Session {
    pub fn new(decision_period: usize) -> Self {
        Self {
            slots: Vec::new(),
            decision_period: decision_period.max(1),
            frames_per_episode: DEFAULT_FRAMES as usize,
            frame_index: 0,
            last_features: Vec::new(),
            broken: Vec::new(),
            run: None,
            episode_started: false,
            placements: Vec::new(),
            pending_rollout: None,
        }
    }

    /// The handshake: the protocol and extension versions, the slot count, and the spec (`spec::handshake_fields`:
    /// its version and hash, rates, every name, the default bag).
    pub fn hello(&self, slot_count: usize) -> Message {
        let mut message = Message::new("hello")
            .with("protocol_version", json!(PROTOCOL_VERSION))
            .with("extension_version", json!(crate::VERSION))
            .with("slot_count", json!(slot_count));
        message.header.extend(handshake_fields(self.decision_period as u32));
        message
    }

    /// Handles one message. Bad requests get an error reply and change nothing.
    pub fn handle(&mut self, message: &Message, world: &mut impl World) -> Outcome {
        let result = match message.message_type() {
            "hello" => self.check_hello(message).map(|()| Outcome::Reply(self.hello(world.slot_count()))),
            "reset" => self.reset(message, world),
            "step" => self.start_step(message, world),
            "rollout" => self.start_rollout(message, world),
            "close" => Ok(Outcome::Close(Message::new("bye"))),
            other => Err(format!("unknown message type '{other}' (expected hello, reset, step, rollout or close)")),
        };
        result.unwrap_or_else(|error| Outcome::Reply(error_reply(&error)))
    }

    fn check_hello(&self, message: &Message) -> Result<(), String> {
        match message.header.get("protocol_version").and_then(Value::as_u64) {
            Some(version) if version == PROTOCOL_VERSION as u64 => Ok(()),
            Some(version) => {
                Err(format!("protocol version {version} is not supported; this server speaks {PROTOCOL_VERSION}"))
            }
            None => Err("hello needs an integer 'protocol_version'".into()),
        }
    }

    fn reset(&mut self, message: &Message, world: &mut impl World) -> Result<Outcome, String> {
        let slot_count = world.slot_count();
        let whole = |key: &str, default: u32| -> Result<u32, String> {
            match message.header.get(key) {
                None => Ok(default),
                Some(value) => value
                    .as_u64()
                    .and_then(|v| u32::try_from(v).ok())
                    .ok_or_else(|| format!("'{key}' must be an integer, not {value}")),
            }
        };
        let spec = PolicySpec::new(
            self.decision_period as u32,
            whole("frames", DEFAULT_FRAMES)?,
            whole("smoothing_window", 1)?,
        )?;
        let placements = parse_placements(message.header.get("bags"), slot_count)?;
        let lead_in = match message.arrays.iter().find(|a| a.name == "lead_in") {
            None => None,
            Some(array) => {
                let decisions = array.shape.get(1).copied().unwrap_or(0);
                let actions =
                    message.array("lead_in", &[slot_count, decisions, DOF_COUNT]).map_err(|e| e.to_string())?;
                if decisions == 0 || decisions > MAX_LEAD_IN_DECISIONS {
                    return Err(format!("a lead-in has 1 to {MAX_LEAD_IN_DECISIONS} decisions, not {decisions}"));
                }
                if actions.data.iter().any(|v| !v.is_finite()) {
                    return Err("the lead-in's actions must be finite".into());
                }
                Some((actions.data.clone(), decisions))
            }
        };
        world.reset(&placements)?;
        self.placements = placements;
        self.frames_per_episode = spec.frames as usize;
        self.frame_index = 0; // a lead-in's frames do not count: the episode's frame 0 comes after them
        match lead_in {
            None => Ok(Outcome::Reply(self.start_episode(spec, world))),
            Some((actions, decisions)) => {
                // Unsmoothed, like the end of an earlier punch's actions; the episode's controllers start fresh.
                self.slots = (0..slot_count).map(|slot| CharacterController::new(world.geometry(slot), 1)).collect();
                self.episode_started = false;
                self.begin(Command::LeadIn(spec), decisions * self.decision_period, actions, decisions, world);
                Ok(Outcome::Running)
            }
        }
    }

    /// Frame 0 of an episode from the world as it is now: fresh controllers (as `PunchController` makes at
    /// every punch), the first features and observations.
    fn start_episode(&mut self, spec: PolicySpec, world: &mut impl World) -> Message {
        let slot_count = world.slot_count();
        self.frame_index = 0;
        self.slots = (0..slot_count)
            .map(|slot| CharacterController::new(world.geometry(slot), spec.smoothing_window as usize))
            .collect();
        self.broken = vec![false; slot_count];
        for (slot, placement) in self.placements.iter().enumerate() {
            if !placement.body.is_still() {
                world.carry_bodies(slot, &placement.body.pose_at(0.0), placement.rides);
            }
        }
        self.last_features = (0..slot_count).map(|slot| self.slots[slot].features(&world.read(slot))).collect();
        self.episode_started = true;
        let mut features = Vec::with_capacity(slot_count * FEATURE_COUNT);
        let mut observations = Vec::with_capacity(slot_count * OBS_DIM);
        for last in &self.last_features {
            features.extend_from_slice(last);
            observations.extend_from_slice(&observation(last, 0, self.decisions_per_episode() as u32));
        }
        Message::new("reset_done")
            .with("frames", json!(spec.frames))
            .with("decisions", json!(self.decisions_per_episode()))
            .with("policy_metadata", spec.metadata_json())
            .with_array(Array::new("observations", vec![slot_count, OBS_DIM], observations))
            .with_array(Array::new("features", vec![slot_count, FEATURE_COUNT], features))
    }

    fn decisions_per_episode(&self) -> usize {
        self.frames_per_episode / self.decision_period
    }

    fn start_step(&mut self, message: &Message, world: &mut impl World) -> Result<Outcome, String> {
        if !self.episode_started {
            return Err("no episode: send reset first".into());
        }
        if self.frame_index >= self.frames_per_episode {
            return Err("the episode is over: send reset".into());
        }
        let slot_count = self.slots.len();
        let actions = message.array("actions", &[slot_count, DOF_COUNT]).map_err(|e| e.to_string())?;
        let mut executed = Vec::with_capacity(slot_count * DOF_COUNT);
        for (slot, action) in self.slots.iter_mut().zip(actions.data.chunks_exact(DOF_COUNT)) {
            executed.extend_from_slice(&slot.set_action(action).map_err(|e| e.to_string())?);
        }
        self.begin(Command::Step, self.decision_period, Vec::new(), 1, world);
        if let Some(run) = self.run.as_mut() {
            run.executed = executed;
        }
        Ok(Outcome::Running)
    }

    fn start_rollout(&mut self, message: &Message, world: &mut impl World) -> Result<Outcome, String> {
        let slot_count = world.slot_count();
        let decisions =
            message.arrays.iter().find(|a| a.name == "actions").and_then(|a| a.shape.get(1).copied()).unwrap_or(0);
        let actions =
            message.array("actions", &[slot_count, decisions, DOF_COUNT]).map_err(|e| e.to_string())?.data.clone();
        if decisions == 0 {
            return Err("a rollout needs at least one decision".into());
        }
        let mut reset = message.clone();
        reset.header.insert("frames".into(), json!(decisions * self.decision_period));
        let outcome = self.reset(&reset, world)?;
        if matches!(outcome, Outcome::Running) {
            // A lead-in plays first (a start from a stance's guard, or after a punch): the rollout follows it.
            self.pending_rollout = Some((actions, decisions));
            return Ok(outcome);
        }
        self.begin(Command::Rollout, decisions * self.decision_period, actions, decisions, world);
        Ok(Outcome::Running)
    }

    fn begin(
        &mut self,
        command: Command,
        frames_total: usize,
        actions: Vec<f32>,
        decisions: usize,
        world: &mut impl World,
    ) {
        let slot_count = self.slots.len();
        self.run = Some(Run {
            command,
            frames_total,
            frames_done: 0,
            actions,
            decisions,
            features: Vec::with_capacity(slot_count * frames_total * FEATURE_COUNT),
            executed: vec![0.0; slot_count * decisions * DOF_COUNT],
        });
        let readings: Vec<FrameReading> = (0..slot_count).map(|slot| world.read(slot)).collect();
        self.drive_all(world, &readings);
    }

    /// Open-loop actions for the decision that starts at the current frame, then motors for every slot,
    /// from this frame's readings (each slot is read from the engine once per frame).
    fn drive_all(&mut self, world: &mut impl World, readings: &[FrameReading]) {
        let Some(run) = self.run.as_mut() else { return };
        let open_loop = matches!(run.command, Command::Rollout | Command::LeadIn(_));
        if open_loop && run.frames_done % self.decision_period == 0 {
            let decision = run.frames_done / self.decision_period;
            for (slot, controller) in self.slots.iter_mut().enumerate() {
                let start = (slot * run.decisions + decision) * DOF_COUNT;
                // Validated as finite when the message arrived, so this cannot fail.
                if let Ok(executed) = controller.set_action(&run.actions[start..start + DOF_COUNT]) {
                    run.executed[start..start + DOF_COUNT].copy_from_slice(&executed);
                }
            }
        }
        for (slot, (controller, reading)) in self.slots.iter().zip(readings).enumerate() {
            world.drive(slot, &controller.motor_commands(reading));
        }
        if !matches!(run.command, Command::LeadIn(_)) {
            // The pelvis and a carried rope reach their places of the frame after this step (still in lead-ins).
            let time_s = (self.frame_index + 1) as f32 / PHYSICS_HZ as f32;
            for (slot, placement) in self.placements.iter().enumerate() {
                if !placement.body.is_still() {
                    world.move_pelvis(slot, &placement.body.pose_at(time_s));
                }
                if placement.glides {
                    let glide = RootPose { position: placement.velocity() * time_s, ..RootPose::START };
                    world.move_rope(slot, &glide);
                } else if placement.rides {
                    world.move_rope(slot, &placement.body.pose_at(time_s));
                }
            }
        }
    }

    /// Call once per physics frame while running (after the engine stepped): records the frame and either
    /// drives the next one or returns the reply.
    pub fn physics_frame(&mut self, world: &mut impl World) -> Option<Message> {
        let run = self.run.as_mut()?;
        let readings: Vec<FrameReading> = (0..self.slots.len()).map(|slot| world.read(slot)).collect();
        let lead_in = match run.command {
            Command::LeadIn(spec) => Some(spec),
            _ => None,
        };
        if lead_in.is_none() {
            for ((slot, controller), reading) in self.slots.iter_mut().enumerate().zip(&readings) {
                let features = controller.features(reading);
                if features[FLAGS] as u32 & guard::JOINT_SEPARATED != 0 {
                    self.broken[slot] = true;
                }
                run.features.extend_from_slice(&features);
                self.last_features[slot] = features;
            }
            self.frame_index += 1;
        }
        run.frames_done += 1;
        if run.frames_done < run.frames_total {
            self.drive_all(world, &readings);
            return None;
        }
        let run = self.run.take()?;
        match lead_in {
            Some(spec) => {
                // The episode starts from the pose the lead-in left, with the bag as placed (a swinging bag is
                // the placement's to say).
                for (slot, placement) in self.placements.iter().enumerate() {
                    world.place_bag(slot, placement);
                }
                let started = self.start_episode(spec, world);
                match self.pending_rollout.take() {
                    Some((actions, decisions)) => {
                        self.begin(Command::Rollout, decisions * self.decision_period, actions, decisions, world);
                        None
                    }
                    None => Some(started),
                }
            }
            None => Some(self.reply(run)),
        }
    }

    fn reply(&self, run: Run) -> Message {
        let slot_count = self.slots.len();
        // Features arrive frame-major ([frame][slot][feature]); replies are slot-major.
        let mut features = vec![0.0f32; run.features.len()];
        for frame in 0..run.frames_total {
            for slot in 0..slot_count {
                let from = (frame * slot_count + slot) * FEATURE_COUNT;
                let to = (slot * run.frames_total + frame) * FEATURE_COUNT;
                features[to..to + FEATURE_COUNT].copy_from_slice(&run.features[from..from + FEATURE_COUNT]);
            }
        }
        let features = Array::new("features", vec![slot_count, run.frames_total, FEATURE_COUNT], features);
        let executed = Array::new("executed_actions", vec![slot_count, run.decisions, DOF_COUNT], run.executed);
        match run.command {
            Command::Rollout | Command::LeadIn(_) => {
                Message::new("rollout_done").with_array(features).with_array(executed)
            }
            Command::Step => {
                let decision = self.frame_index / self.decision_period;
                let over = self.frame_index >= self.frames_per_episode;
                let mut observations = Vec::with_capacity(slot_count * OBS_DIM);
                for last in &self.last_features {
                    observations.extend_from_slice(&observation(
                        last,
                        decision as u32,
                        self.decisions_per_episode() as u32,
                    ));
                }
                // Episodes have a fixed length that the observation shows (episode_phase), so reaching it
                // terminates; a slot whose physics broke on the way (a joint came apart) ends truncated.
                let terminated: Vec<bool> = self.broken.iter().map(|&broken| over && !broken).collect();
                let truncated: Vec<bool> = self.broken.iter().map(|&broken| over && broken).collect();
                Message::new("step_done")
                    .with("decision", json!(decision))
                    .with("terminated", json!(terminated))
                    .with("truncated", json!(truncated))
                    .with_array(Array::new("observations", vec![slot_count, OBS_DIM], observations))
                    .with_array(features)
                    .with_array(executed)
            }
        }
    }
}

fn parse_placements(value: Option<&Value>, slot_count: usize) -> Result<Vec<EpisodeConditions>, String> {
    const NAMES: &str = "distance_m, height_m, side_m, velocity_side_mps, velocity_forward_mps, bag_glides, bag_rides, \
                         body_side_mps, body_forward_mps, body_turn_rad_s, body_lunge_m, body_bob_m, \
                         arms_upper_arm_scale, arms_forearm_scale, arms_shoulder_shift_m";
    let parse_one = |value: &Value| -> Result<EpisodeConditions, String> {
        let object = value.as_object().ok_or("a bag placement is an object")?;
        let mut placement = EpisodeConditions::default();
        for (key, field) in object {
            if key == "bag_glides" || key == "bag_rides" {
                let value = field.as_bool().ok_or(format!("bag '{key}' must be true or false"))?;
                *(if key == "bag_glides" { &mut placement.glides } else { &mut placement.rides }) = value;
                continue;
            }
            let number =
                field.as_f64().filter(|v| v.is_finite()).ok_or(format!("bag '{key}' must be a finite number"))? as f32;
            match placement.arms.set(key, number) {
                Some(true) => continue,
                Some(false) => return Err(format!("bag '{key}' = {number} is out of range")),
                None => {}
            }
            let motion_limit = motion::FIELDS.iter().find(|(name, _)| name == key).map(|(_, limit)| *limit);
            match key.as_str() {
                "distance_m" if (0.3..=3.0).contains(&number) => placement.distance_m = number,
                "height_m" if (0.6..=2.2).contains(&number) => placement.height_m = number,
                "side_m" if (-1.5..=1.5).contains(&number) => placement.side_m = number,
                "velocity_side_mps" if number.abs() <= 3.0 => placement.velocity_side_mps = number,
                "velocity_forward_mps" if number.abs() <= 3.0 => placement.velocity_forward_mps = number,
                _ if motion_limit.is_some_and(|limit| number.abs() <= limit) => {
                    placement.body.set(key, number);
                }
                "distance_m" | "height_m" | "side_m" | "velocity_side_mps" | "velocity_forward_mps" => {
                    return Err(format!("bag '{key}' = {number} is out of range"));
                }
                _ if motion_limit.is_some() => return Err(format!("bag '{key}' = {number} is out of range")),
                _ => return Err(format!("unknown bag field '{key}' ({NAMES})")),
            }
        }
        if placement.glides && placement.rides {
            return Err("a bag either glides (its rope carried at its velocity) or rides along with the character, \
                        not both"
                .into());
        }
        Ok(placement)
    };
    match value {
        None | Some(Value::Null) => Ok(vec![EpisodeConditions::default(); slot_count]),
        Some(Value::Array(list)) if list.len() == slot_count => list.iter().map(parse_one).collect(),
        Some(Value::Array(list)) => Err(format!("'bags' lists {} placements for {slot_count} slots", list.len())),
        Some(one) => Ok(vec![parse_one(one)?; slot_count]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::observation::observation_names;
    use crate::contract::sensing::feature_index;
    use crate::contract::spec::keys;
    use crate::fake_world::FakeWorld;

    fn message(text: serde_json::Value, actions: Option<Array>) -> Message {
        let mut message = Message::new(text["type"].as_str().expect("type"));
        for (key, value) in text.as_object().expect("object") {
            message.header.insert(key.clone(), value.clone());
        }
        message.arrays.extend(actions);
        message
    }

    fn reply(outcome: Outcome) -> Message {
        match outcome {
            Outcome::Reply(reply) | Outcome::Close(reply) => reply,
            Outcome::Running => panic!("expected a reply, the session is running"),
        }
    }

    /// Steps the fake world until the session replies; returns the reply and the frames it took.
    fn run(session: &mut Session, world: &mut FakeWorld) -> (Message, usize) {
        for frames in 1..=10_000 {
            world.step();
            if let Some(reply) = session.physics_frame(world) {
                return (reply, frames);
            }
        }
        panic!("the session never replied");
    }

    #[test]
    fn the_handshake_carries_the_spec() {
        let (mut session, mut world) = (Session::new(5), FakeWorld::new(3));
        let hello = reply(
            session.handle(&message(json!({"type": "hello", "protocol_version": PROTOCOL_VERSION}), None), &mut world),
        );
        assert_eq!(hello.header["slot_count"], json!(3));
        assert_eq!(hello.header["spec_hash"], json!(crate::contract::spec::spec_hash(5)));
        assert_eq!(hello.header["default_bag"], EpisodeConditions::DEFAULT.to_json());
        let old = reply(session.handle(&message(json!({"type": "hello", "protocol_version": 1}), None), &mut world));
        assert_eq!(old.message_type(), "error");
    }

    #[test]
    fn reset_announces_the_policy_contract_of_its_episodes() {
        let (mut session, mut world) = (Session::new(5), FakeWorld::new(2));
        let reset = reply(
            session.handle(&message(json!({"type": "reset", "frames": 100, "smoothing_window": 3}), None), &mut world),
        );
        assert_eq!(reset.message_type(), "reset_done");
        let contract = &reset.header["policy_metadata"];
        assert_eq!(contract[keys::FRAMES], json!("100"));
        assert_eq!(contract[keys::SMOOTHING_WINDOW], json!("3"));
        assert_eq!(contract[keys::DECISION_PERIOD], json!("5"));
        assert_eq!(reset.array("observations", &[2, OBS_DIM]).expect("observations").data[OBS_DIM - 1], 0.0);
        for bad in [
            json!({"type": "reset", "frames": 7}),
            json!({"type": "reset", "smoothing_window": 0}),
            json!({"type": "reset", "bags": {"height_m": 9.0}}),
        ] {
            assert_eq!(reply(session.handle(&message(bad.clone(), None), &mut world)).message_type(), "error", "{bad}");
        }
    }

    #[test]
    fn a_step_runs_one_decision_period_and_the_episode_ends_after_its_frames() {
        let (mut session, mut world) = (Session::new(5), FakeWorld::new(2));
        let step = || {
            message(json!({"type": "step"}), Some(Array::new("actions", vec![2, DOF_COUNT], vec![0.5; 2 * DOF_COUNT])))
        };
        assert_eq!(reply(session.handle(&step(), &mut world)).message_type(), "error", "no episode yet");
        reply(session.handle(&message(json!({"type": "reset", "frames": 10}), None), &mut world));
        for decision in 1..=2 {
            assert!(matches!(session.handle(&step(), &mut world), Outcome::Running));
            let (done, frames) = run(&mut session, &mut world);
            assert_eq!((done.message_type(), frames), ("step_done", 5));
            assert_eq!(done.header["decision"], json!(decision));
            assert_eq!(done.header["terminated"], json!([decision == 2, decision == 2]));
            assert_eq!(
                done.array("features", &[2, 5, FEATURE_COUNT]).expect("features").shape,
                vec![2, 5, FEATURE_COUNT]
            );
        }
        assert_eq!(reply(session.handle(&step(), &mut world)).message_type(), "error", "the episode is over");
    }

    #[test]
    fn a_rollout_plays_its_actions_open_loop_from_a_fresh_reset() {
        let (mut session, mut world) = (Session::new(5), FakeWorld::new(2));
        let mut actions = vec![0.0; 2 * 4 * DOF_COUNT];
        actions[..4 * DOF_COUNT].fill(0.8); // slot 0 punches, slot 1 holds its guard
        let rollout = message(
            json!({"type": "rollout", "smoothing_window": 2}),
            Some(Array::new("actions", vec![2, 4, DOF_COUNT], actions)),
        );
        assert!(matches!(session.handle(&rollout, &mut world), Outcome::Running));
        let (done, frames) = run(&mut session, &mut world);
        assert_eq!((done.message_type(), frames, world.resets), ("rollout_done", 20, 1));
        let features = done.array("features", &[2, 20, FEATURE_COUNT]).expect("features");
        // The fake character slides whole (its root too): the bag comes nearer in its frame.
        let bag_z = feature_index("bag_pos_z").expect("feature");
        let bag_z = |slot: usize, frame: usize| features.data[(slot * 20 + frame) * FEATURE_COUNT + bag_z];
        assert!(bag_z(0, 19) < bag_z(0, 0) - 0.1 && bag_z(1, 19) == bag_z(1, 0));
        let executed = done.array("executed_actions", &[2, 4, DOF_COUNT]).expect("executed");
        assert_eq!(executed.data[0], 0.8, "smoothing starts from the first action itself");
        assert_eq!(world.driven.len(), 2 * 20, "every slot driven once per frame");
    }

    #[test]
    fn a_reset_with_a_lead_in_starts_the_episode_where_the_lead_in_left_each_character() {
        let (mut session, mut world) = (Session::new(5), FakeWorld::new(2));
        let mut lead_in = vec![0.0; 2 * 3 * DOF_COUNT];
        lead_in[..3 * DOF_COUNT].fill(0.8); // slot 0 moves before its episode, slot 1 stays in guard
        let reset = message(
            json!({"type": "reset", "frames": 10, "smoothing_window": 3}),
            Some(Array::new("lead_in", vec![2, 3, DOF_COUNT], lead_in)),
        );
        assert!(matches!(session.handle(&reset, &mut world), Outcome::Running));
        let (done, frames) = run(&mut session, &mut world);
        assert_eq!((done.message_type(), frames), ("reset_done", 15));
        let observations = done.array("observations", &[2, OBS_DIM]).expect("observations").data.clone();
        let bag_z = observation_names().iter().position(|name| *name == "bag_pos_z").expect("observed");
        assert!(observations[bag_z] < observations[OBS_DIM + bag_z] - 0.05, "slot 0 starts nearer its bag");
        assert_eq!((observations[OBS_DIM - 1], observations[2 * OBS_DIM - 1]), (0.0, 0.0), "phase 0");
        // The episode then runs its full length.
        let step = message(json!({"type": "step"}), Some(Array::new("actions", vec![2, DOF_COUNT], vec![0.0; 20])));
        assert!(matches!(session.handle(&step, &mut world), Outcome::Running));
        assert_eq!(run(&mut session, &mut world).0.header["decision"], json!(1));
        for (bad, shape) in [(f32::NAN, vec![2, 1, DOF_COUNT]), (0.0, vec![1, 1, DOF_COUNT])] {
            let count = shape.iter().product();
            let reset = message(json!({"type": "reset"}), Some(Array::new("lead_in", shape, vec![bad; count])));
            assert_eq!(reply(session.handle(&reset, &mut world)).message_type(), "error");
        }
    }

    #[test]
    fn a_rollout_with_a_lead_in_starts_where_the_lead_in_left_each_character() {
        let (mut session, mut world) = (Session::new(5), FakeWorld::new(2));
        let mut lead_in = vec![0.0; 2 * 3 * DOF_COUNT];
        lead_in[..3 * DOF_COUNT].fill(0.8); // slot 0 moves before its rollout, slot 1 stays in guard
        let rollout = Message::new("rollout")
            .with_array(Array::new("actions", vec![2, 2, DOF_COUNT], vec![0.0; 2 * 2 * DOF_COUNT]))
            .with_array(Array::new("lead_in", vec![2, 3, DOF_COUNT], lead_in));
        assert!(matches!(session.handle(&rollout, &mut world), Outcome::Running));
        let (done, frames) = run(&mut session, &mut world);
        assert_eq!((done.message_type(), frames), ("rollout_done", 25), "15 lead-in frames, then 10 recorded");
        let features = done.array("features", &[2, 10, FEATURE_COUNT]).expect("only the rollout's frames");
        let bag_z = feature_index("bag_pos_z").expect("feature");
        let first = |slot: usize| features.data[slot * 10 * FEATURE_COUNT + bag_z];
        assert!(first(0) < first(1) - 0.05, "slot 0 starts nearer its bag: {} against {}", first(0), first(1));
        // The next rollout without one starts from the guard again.
        let plain = Message::new("rollout").with_array(Array::new("actions", vec![2, 2, DOF_COUNT], vec![0.0; 40]));
        assert!(matches!(session.handle(&plain, &mut world), Outcome::Running));
        assert_eq!(run(&mut session, &mut world).1, 10);
    }

    #[test]
    fn a_walking_slot_has_its_pelvis_carried_every_frame_and_a_standing_one_never() {
        let (mut session, mut world) = (Session::new(5), FakeWorld::new(2));
        let bags = json!([{"body_forward_mps": 1.4, "body_turn_rad_s": 1.5, "bag_glides": true,
                           "velocity_forward_mps": 1.0}, {}]);
        reply(session.handle(&message(json!({"type": "reset", "frames": 10, "bags": bags}), None), &mut world));
        let walking = EpisodeConditions { velocity_forward_mps: 1.0, glides: true, ..EpisodeConditions::DEFAULT };
        assert_eq!(session.placements[0].body.forward_mps, 1.4);
        assert_eq!(
            (session.placements[0].glides, session.placements[0].velocity()),
            (walking.glides, walking.velocity())
        );
        assert_eq!(world.carried.len(), 1, "the walking slot starts walking");
        assert_eq!(world.carried[0].1.linear_velocity, Vec3::new(0.0, 0.0, 1.4));
        let step = message(json!({"type": "step"}), Some(Array::new("actions", vec![2, DOF_COUNT], vec![0.0; 20])));
        assert!(matches!(session.handle(&step, &mut world), Outcome::Running));
        run(&mut session, &mut world);
        assert_eq!(world.pelvis_moves.len(), 5, "once per frame, only the walking slot");
        assert_eq!(world.ropes.len(), 5, "and its gliding bag's rope");
        assert_eq!(world.ropes[4], (0, Vec3::new(0.0, 0.0, 5.0 / PHYSICS_HZ as f32)));
        for (frame, (slot, pose)) in world.pelvis_moves.iter().enumerate() {
            let expected = session.placements[0].body.pose_at((frame + 1) as f32 / PHYSICS_HZ as f32);
            assert_eq!((*slot, *pose), (0, expected));
        }
        let riding = json!([{"body_side_mps": 0.7, "body_turn_rad_s": 1.0, "bag_rides": true}, {}]);
        reply(session.handle(&message(json!({"type": "reset", "frames": 10, "bags": riding}), None), &mut world));
        assert!(world.carried.last().is_some_and(|(slot, _)| *slot == 0));
        assert!(matches!(session.handle(&step, &mut world), Outcome::Running));
        run(&mut session, &mut world);
        let expected = session.placements[0].body.pose_at(5.0 / PHYSICS_HZ as f32);
        assert_eq!(world.ropes.last().map(|(slot, _)| *slot), Some(0));
        assert_eq!(world.ropes.last().map(|(_, moved)| *moved), Some(expected.position), "carried with the body");
        let both = json!({"bag_glides": true, "bag_rides": true});
        for bad in [json!({"body_forward_mps": 9.0}), json!({"bag_glides": 1}), json!({"body_fly": 1.0}), both] {
            let reset = message(json!({"type": "reset", "bags": bad}), None);
            assert_eq!(reply(session.handle(&reset, &mut world)).message_type(), "error", "{bad}");
        }
    }

    #[test]
    fn a_bag_may_start_moving() {
        let placements =
            parse_placements(Some(&json!({"velocity_side_mps": 0.5, "velocity_forward_mps": -1.0})), 2).expect("valid");
        assert_eq!(placements[1].velocity(), Vec3::new(0.5, 0.0, -1.0));
        assert!(parse_placements(Some(&json!({"velocity_side_mps": 4.0})), 1).is_err());
    }

    #[test]
    fn a_placement_may_size_the_arms_within_the_range_a_rig_may_have() {
        let placements =
            parse_placements(Some(&json!({"arms_upper_arm_scale": 0.8, "arms_shoulder_shift_m": 0.02})), 1)
                .expect("valid");
        assert_eq!(placements[0].arms.upper_arm, 0.8);
        assert_eq!(placements[0].arms.forearm, 1.0);
        assert_eq!(placements[0].arms.shoulder_shift_m, 0.02);
        let error = parse_placements(Some(&json!({"arms_forearm_scale": 2.0})), 1).expect_err("too long");
        assert!(error.contains("arms_forearm_scale"), "{error}");
        let written = placements[0].to_json();
        assert_eq!(written["arms_upper_arm_scale"].as_f64().map(|v| v as f32), Some(0.8));
    }
}
