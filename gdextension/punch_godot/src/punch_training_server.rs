//! `PunchTrainingServer`: the headless training world. It serves the trainer over TCP on loopback and runs
//! N characters, each with its own bag, in lockstep with Godot's physics.
//!
//! The world itself (physics-server bodies built from the addon's scenes, isolation, exact resets) is in
//! `training_world.rs`.
//!
//! Lockstep: while waiting for a command the server blocks inside `physics_process`, so no physics step
//! happens between commands; a command that needs frames returns and lets Godot step.

use std::time::Duration;

use godot::classes::{Engine, INode, Node, Os, PackedScene};
use godot::global::{godot_error, godot_print, godot_warn};
use godot::obj::{Base, Gd, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::contract::character::{DEFAULT_DECISION_PERIOD, PHYSICS_HZ};
use punch_core::contract::spec::EpisodeConditions;
use punch_core::training::access::ClientId;
use punch_core::training::connections::{Connections, Limits};
use punch_core::training::session::{Outcome, Session, World};

use crate::training_world::{MAX_SLOTS_PER_WORLD, TrainingWorld};

/// The headless training server the Python trainer starts and drives (see docs/protocol.md). Command-line
/// arguments after `--` override the exported values: `--port=`, `--slots=`, `--decision-period=`,
/// `--idle-timeout-s=`.
#[derive(GodotClass)]
#[class(base = Node, init)]
pub struct PunchTrainingServer {
    /// TCP port on 127.0.0.1; 0 picks a free port (printed in the ready line).
    #[export(range = (0.0, 65535.0, 1.0))]
    port: i32,
    /// Number of characters simulated side by side (N).
    #[export(range = (1.0, 4096.0, 1.0))]
    #[init(val = 1)]
    slot_count: i32,
    /// Physics frames each action is held for.
    #[export(range = (1.0, 60.0, 1.0, suffix = "frames"))]
    #[init(val = DEFAULT_DECISION_PERIOD as i32)]
    decision_period: i32,
    /// Characters sharing one physics world (1 to 16). 1 makes every slot bitwise identical whatever its
    /// index, at about 2.7 times the cost; see docs/env.md.
    #[export(range = (1.0, 16.0, 1.0))]
    #[init(val = 16)]
    slots_per_world: i32,
    /// Seconds without a client (or without a message from it) after which the server quits.
    #[export(range = (1.0, 3600.0, 1.0, or_greater, suffix = "s"))]
    #[init(val = 120.0)]
    idle_timeout_s: f32,
    /// The character scene (the addon's punch_character.tscn).
    #[export]
    character_scene: Option<Gd<PackedScene>>,
    /// The sandbag scene (the addon's punch_sandbag.tscn).
    #[export]
    sandbag_scene: Option<Gd<PackedScene>>,

    connections: Option<Connections>,
    session: Option<Session>,
    world: Option<TrainingWorld>,
    /// The client whose command is running, if one is.
    running: Option<ClientId>,
    base: Base<Node>,
}

#[godot_api]
impl INode for PunchTrainingServer {
    fn ready(&mut self) {
        if let Err(error) = self.start() {
            godot_error!("PunchTrainingServer: {error}");
            self.quit(1);
        }
    }

    fn physics_process(&mut self, _delta: f64) {
        if self.world.is_none() {
            return;
        }
        if let Some(client) = self.running {
            let (Some(session), Some(world)) = (self.session.as_mut(), self.world.as_mut()) else {
                return;
            };
            match session.physics_frame(world) {
                Some(reply) => {
                    self.running = None;
                    self.send(client, &reply);
                }
                None => {
                    // Replies to other clients go on leaving while physics runs.
                    self.flush_all();
                    return;
                }
            }
        }
        self.serve();
    }
}

impl PunchTrainingServer {
    fn start(&mut self) -> Result<(), String> {
        for argument in Os::singleton().get_cmdline_user_args().as_slice() {
            let argument = argument.to_string();
            let Some((key, value)) = argument.trim_start_matches("--").split_once('=') else {
                continue;
            };
            let number = || value.parse::<f64>().map_err(|_| format!("--{key}={value}: not a number"));
            match key {
                "port" => self.port = number()? as i32,
                "slots" => self.slot_count = number()? as i32,
                "decision-period" => self.decision_period = number()? as i32,
                "idle-timeout-s" => self.idle_timeout_s = number()? as f32,
                "slots-per-world" => self.slots_per_world = number()? as i32,
                _ => {}
            }
        }
        let ticks = Engine::singleton().get_physics_ticks_per_second();
        if ticks != PHYSICS_HZ as i32 {
            return Err(format!("physics runs at {ticks} Hz; the punch spec needs {PHYSICS_HZ} Hz"));
        }
        if !(1..=4096).contains(&self.slot_count)
            || !(1..=60).contains(&self.decision_period)
            || !(0..=65535).contains(&self.port)
        {
            return Err(format!(
                "bad settings: slots {} (1..=4096), decision period {} (1..=60), port {}",
                self.slot_count, self.decision_period, self.port
            ));
        }
        // The run's secret comes in the environment (which other users cannot read), never as an argument.
        let os = Os::singleton();
        let secret = os.get_environment(SECRET_VARIABLE).to_string();
        // Unsetting alone leaves it where /proc/PID/environ shows the environment the process started with.
        punch_core::training::access::scrub_environment_variable(SECRET_VARIABLE);
        os.unset_environment(SECRET_VARIABLE);
        if secret.is_empty() {
            return Err(format!(
                "{SECRET_VARIABLE} is not set: the server only serves the run that started it (the trainer sets a \
                 fresh secret; see docs/protocol.md, Access)"
            ));
        }
        let character_scene = self.character_scene.clone().ok_or("no character_scene set")?;
        let sandbag_scene = self.sandbag_scene.clone().ok_or("no sandbag_scene set")?;
        let connections = Connections::listen(self.port as u16, &secret, Limits::default())?;
        let port = connections.port();
        self.connections = Some(connections);
        if !(1..=MAX_SLOTS_PER_WORLD as i32).contains(&self.slots_per_world) {
            return Err(format!("slots per world must be 1..={MAX_SLOTS_PER_WORLD}, not {}", self.slots_per_world));
        }
        let mut world = TrainingWorld::new(
            &character_scene,
            &sandbag_scene,
            self.slot_count as usize,
            self.slots_per_world as usize,
        )?;
        world.reset(&vec![EpisodeConditions::default(); self.slot_count as usize])?;
        self.world = Some(world);
        self.session = Some(Session::new(self.decision_period as usize));
        godot_print!(
            "PUNCH_SERVER_READY port={port} slots={} decision_period={}",
            self.slot_count,
            self.decision_period
        );
        Ok(())
    }

    /// Answers requests from every client until one starts a physics run, or quits when idle too long.
    fn serve(&mut self) {
        if let Some(connections) = self.connections.as_mut() {
            connections.note_activity();
        }
        loop {
            let Some(connections) = self.connections.as_mut() else { return };
            let request = connections.next_request();
            for notice in connections.take_notices() {
                godot_warn!("PunchTrainingServer: {notice}");
            }
            let Some((client, message)) = request else {
                if connections.idle_for() > Duration::from_secs_f32(self.idle_timeout_s.max(0.0)) {
                    godot_print!("PunchTrainingServer: no request for {} s, quitting", self.idle_timeout_s);
                    self.quit(0);
                    return;
                }
                continue;
            };
            let (Some(session), Some(world)) = (self.session.as_mut(), self.world.as_mut()) else {
                return;
            };
            match session.handle(&message, world) {
                Outcome::Reply(reply) => connections.send(client, &reply),
                Outcome::Running => {
                    self.running = Some(client);
                    return;
                }
                Outcome::Close(reply) => connections.close_after(client, &reply),
            }
        }
    }

    /// Sends what every socket takes now (replies go on leaving while physics runs).
    fn flush_all(&mut self) {
        if let Some(connections) = self.connections.as_mut() {
            connections.flush_all();
            for notice in connections.take_notices() {
                godot_warn!("PunchTrainingServer: {notice}");
            }
        }
    }

    fn send(&mut self, client: ClientId, message: &punch_core::training::protocol::Message) {
        if let Some(connections) = self.connections.as_mut() {
            connections.send(client, message);
        }
    }

    fn quit(&mut self, code: i32) {
        self.world = None;
        self.base().get_tree().quit_ex().exit_code(code).done();
    }
}

/// The environment variable that carries the run's secret to the server.
pub const SECRET_VARIABLE: &str = "PUNCH_SERVER_SECRET";
