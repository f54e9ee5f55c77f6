//! `PunchTrainingServer`: the headless training world. It serves the trainer over TCP on loopback and runs
//! N characters, each with its own bag, in lockstep with Godot's physics.
//!
//! The world itself (physics-server bodies built from the addon's scenes, isolation, exact resets) is in
//! `training_world.rs`.
//!
//! Lockstep: while waiting for a command the server blocks inside `physics_process`, so no physics step
//! happens between commands; a command that needs frames returns and lets Godot step.

use std::io::ErrorKind;
use std::net::{TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

use godot::classes::{Engine, INode, Node, Os, PackedScene};
use godot::global::{godot_error, godot_print};
use godot::obj::{Base, Gd, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::character::{DEFAULT_DECISION_PERIOD, PHYSICS_HZ};
use punch_core::protocol::{FrameReader, Message, ProtocolError, error_reply};
use punch_core::session::{BagPlacement, Outcome, Session, World};

use crate::training_world::{MAX_SLOTS_PER_WORLD, TrainingWorld};

/// Bytes read from a client at most per poll round (a rollout request of 64 characters is about 26 kB).
const RECEIVE_CHUNK_BYTES: usize = 64 * 1024;

/// A client: its socket and the bytes of its next message so far.
struct Connection {
    stream: TcpStream,
    frames: FrameReader,
}

/// The headless training server the Python trainer starts and drives (see docs/protocol.md). Command-line
/// arguments after `--` override the exported values: `--port=`, `--slots=`, `--decision-period=`,
/// `--idle-timeout-s=`.
#[derive(GodotClass)]
#[class(base = Node, init)]
pub struct PunchTrainingServer {
    /// TCP port on 127.0.0.1; 0 picks a free port (printed in the ready line).
    #[export]
    port: i32,
    /// Number of characters simulated side by side (N).
    #[export]
    #[init(val = 1)]
    slot_count: i32,
    /// Physics frames each action is held for.
    #[export]
    #[init(val = DEFAULT_DECISION_PERIOD as i32)]
    decision_period: i32,
    /// Characters sharing one physics world (1 to 16). 1 makes every slot bitwise identical whatever its
    /// index, at about 2.7 times the cost; see docs/env.md.
    #[export]
    #[init(val = 16)]
    slots_per_world: i32,
    /// Seconds without a client (or without a message from it) after which the server quits.
    #[export]
    #[init(val = 120.0)]
    idle_timeout_s: f32,
    /// The character scene (the addon's punch_character.tscn).
    #[export]
    character_scene: Option<Gd<PackedScene>>,
    /// The sandbag scene (the addon's punch_sandbag.tscn).
    #[export]
    sandbag_scene: Option<Gd<PackedScene>>,

    listener: Option<TcpListener>,
    connections: Vec<Connection>,
    session: Option<Session>,
    world: Option<TrainingWorld>,
    /// The client whose command is running, if one is.
    running: Option<usize>,
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
                None => return,
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
        let character_scene = self.character_scene.clone().ok_or("no character_scene set")?;
        let sandbag_scene = self.sandbag_scene.clone().ok_or("no sandbag_scene set")?;
        let listener = TcpListener::bind(("127.0.0.1", self.port as u16))
            .map_err(|e| format!("cannot listen on port {}: {e}", self.port))?;
        let port = listener.local_addr().map_err(|e| e.to_string())?.port();
        listener.set_nonblocking(true).map_err(|e| e.to_string())?;
        self.listener = Some(listener);
        if !(1..=MAX_SLOTS_PER_WORLD as i32).contains(&self.slots_per_world) {
            return Err(format!("slots per world must be 1..={MAX_SLOTS_PER_WORLD}, not {}", self.slots_per_world));
        }
        let mut world = TrainingWorld::new(
            &character_scene,
            &sandbag_scene,
            self.slot_count as usize,
            self.slots_per_world as usize,
        )?;
        world.reset(&vec![BagPlacement::default(); self.slot_count as usize])?;
        self.world = Some(world);
        self.session = Some(Session::new(self.decision_period as usize));
        godot_print!(
            "PUNCH_SERVER_READY port={port} slots={} decision_period={}",
            self.slot_count,
            self.decision_period
        );
        Ok(())
    }

    /// Answers messages from every client until one starts a physics run, or quits when idle too long.
    /// Bytes are collected per client as they arrive, so a client that sends half a frame holds up no one.
    fn serve(&mut self) {
        let mut last_activity = Instant::now();
        loop {
            self.accept_pending();
            let Some((index, result)) = self.next_buffered_message() else {
                match self.wait_readable() {
                    Some(index) => {
                        last_activity = Instant::now();
                        self.receive_bytes(index);
                    }
                    None if last_activity.elapsed().as_secs_f32() > self.idle_timeout_s => {
                        godot_print!("PunchTrainingServer: no request for {} s, quitting", self.idle_timeout_s);
                        self.quit(0);
                        return;
                    }
                    None => {}
                }
                continue;
            };
            let message = match result {
                Ok(message) => message,
                Err(ProtocolError::Content(reason)) => {
                    self.send(index, &error_reply(&reason));
                    continue;
                }
                Err(ProtocolError::Framing(reason)) => {
                    // This stream cannot be resynchronised: say why and drop this client only.
                    self.send(index, &error_reply(&format!("{reason}; closing the connection")));
                    self.connections.remove(index);
                    continue;
                }
                Err(ProtocolError::Closed | ProtocolError::Io(_)) => {
                    self.connections.remove(index);
                    continue;
                }
            };
            let (Some(session), Some(world)) = (self.session.as_mut(), self.world.as_mut()) else {
                return;
            };
            match session.handle(&message, world) {
                Outcome::Reply(reply) => self.send(index, &reply),
                Outcome::Running => {
                    self.running = Some(index);
                    return;
                }
                Outcome::Close(reply) => {
                    self.send(index, &reply);
                    self.connections.remove(index);
                }
            }
        }
    }

    /// A complete message some client has already sent, if any.
    fn next_buffered_message(&mut self) -> Option<(usize, Result<Message, ProtocolError>)> {
        self.connections.iter_mut().enumerate().find_map(|(index, c)| c.frames.next_message().map(|r| (index, r)))
    }

    /// Reads what a readable client has sent (poll said it is readable, so this does not block).
    fn receive_bytes(&mut self, index: usize) {
        let Connection { stream, frames } = &mut self.connections[index];
        match frames.read_available(stream, RECEIVE_CHUNK_BYTES) {
            Ok(0) => {
                self.connections.remove(index);
            }
            Ok(_) => {}
            Err(error) if matches!(error.kind(), ErrorKind::Interrupted | ErrorKind::WouldBlock) => {}
            Err(_) => {
                self.connections.remove(index);
            }
        }
    }

    /// Takes every client waiting in the listen queue.
    fn accept_pending(&mut self) {
        let Some(listener) = &self.listener else {
            return;
        };
        loop {
            match listener.accept() {
                Ok((stream, _)) => {
                    let timeout = Some(Duration::from_secs_f32(self.idle_timeout_s.max(0.1)));
                    if stream.set_nonblocking(false).is_ok()
                        && stream.set_nodelay(true).is_ok()
                        && stream.set_read_timeout(timeout).is_ok()
                    {
                        self.connections.push(Connection { stream, frames: FrameReader::default() });
                    }
                }
                Err(error) if error.kind() == ErrorKind::WouldBlock => return,
                Err(error) => {
                    godot_error!("PunchTrainingServer: accept failed: {error}");
                    return;
                }
            }
        }
    }

    /// Index of a client with bytes to read, waiting up to 20 ms (the listener is polled too, so a new
    /// client is taken on the next round).
    fn wait_readable(&self) -> Option<usize> {
        let mut fds: Vec<libc::pollfd> = self
            .connections
            .iter()
            .map(|c| libc::pollfd { fd: c.stream.as_raw_fd(), events: libc::POLLIN, revents: 0 })
            .collect();
        if let Some(listener) = &self.listener {
            fds.push(libc::pollfd { fd: listener.as_raw_fd(), events: libc::POLLIN, revents: 0 });
        }
        // SAFETY: `fds` is a valid array of pollfd for the duration of the call.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, 20) };
        if ready <= 0 {
            return None;
        }
        fds[..self.connections.len()]
            .iter()
            .position(|fd| fd.revents & (libc::POLLIN | libc::POLLHUP | libc::POLLERR) != 0)
    }

    fn send(&mut self, index: usize, message: &Message) {
        let Some(connection) = self.connections.get_mut(index) else {
            return;
        };
        if message.write_to(&mut connection.stream).is_err() {
            self.connections.remove(index);
        }
    }

    fn quit(&mut self, code: i32) {
        self.world = None;
        self.base().get_tree().quit_ex().exit_code(code).done();
    }
}
