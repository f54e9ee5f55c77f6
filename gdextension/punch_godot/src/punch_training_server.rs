//! `PunchTrainingServer`: the headless training world. It serves the trainer over TCP on loopback and runs
//! N characters, each with its own bag, in lockstep with Godot's physics.
//!
//! The world itself (physics-server bodies built from the addon's scenes, isolation, exact resets) is in
//! `training_world.rs`.
//!
//! Lockstep: while waiting for a command the server blocks inside `physics_process`, so no physics step
//! happens between commands; a command that needs frames returns and lets Godot step.

use std::io::{ErrorKind, Write};
use std::net::{TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::time::Instant;

use godot::classes::{Engine, INode, Node, Os, PackedScene};
use godot::global::{godot_error, godot_print, godot_warn};
use godot::obj::{Base, Gd, Singleton, WithBaseField};
use godot::prelude::{GodotClass, godot_api};
use punch_core::access::{Access, ClientId, Verdict};
use punch_core::character::{DEFAULT_DECISION_PERIOD, PHYSICS_HZ};
use punch_core::protocol::{FrameReader, Message, ProtocolError, error_reply};
use punch_core::session::{BagPlacement, Outcome, Session, World};

use crate::training_world::{MAX_SLOTS_PER_WORLD, TrainingWorld};

/// Bytes read from a client at most per poll round (a rollout request of 64 characters is about 26 kB).
const RECEIVE_CHUNK_BYTES: usize = 64 * 1024;
/// Open connections at most; more are answered with an error and closed.
const MAX_CONNECTIONS: usize = 8;
/// Largest payload from a connection that has not yet said hello with the secret (a hello has none).
const UNAUTHENTICATED_PAYLOAD_BYTES: usize = 0;
/// Seconds a new connection has to say hello with the secret.
const HELLO_TIMEOUT_S: f32 = 10.0;
/// Bytes all connections together may hold, received and not yet handled or to be sent (half-sent frames
/// included); a connection whose next read would go over it is closed.
const MEMORY_BUDGET_BYTES: usize = 512 * 1024 * 1024;
/// Seconds a reply may wait with none of it read by its client; then the client is closed. While a
/// connection's reply waits, its further requests are not read (a client that never reads only fills its
/// own socket).
const UNREAD_REPLY_TIMEOUT_S: f32 = 60.0;

/// A client: its socket (non-blocking), the bytes of its next message so far, and what is still to be sent
/// to it.
struct Connection {
    id: ClientId,
    stream: TcpStream,
    frames: FrameReader,
    /// Encoded replies not yet taken by the client, and since when it has taken none of them.
    outbox: Vec<u8>,
    stalled_since: Option<Instant>,
    opened: Instant,
    /// Close once the outbox is sent (after a `bye` or an error that ends the connection).
    closing: bool,
}

impl Connection {
    /// Writes what the socket takes now. Err: the client is gone.
    fn flush(&mut self) -> std::io::Result<()> {
        while !self.outbox.is_empty() {
            match self.stream.write(&self.outbox) {
                Ok(0) => return Err(ErrorKind::WriteZero.into()),
                Ok(written) => {
                    self.outbox.drain(..written);
                    self.stalled_since = (!self.outbox.is_empty()).then(Instant::now);
                }
                Err(error) if error.kind() == ErrorKind::WouldBlock => {
                    self.stalled_since.get_or_insert_with(Instant::now);
                    return Ok(());
                }
                Err(error) if error.kind() == ErrorKind::Interrupted => {}
                Err(error) => return Err(error),
            }
        }
        self.stalled_since = None;
        Ok(())
    }

    /// Whether its next message may be handled: nothing of an earlier reply is waiting.
    fn ready_for_requests(&self) -> bool {
        self.outbox.is_empty() && !self.closing
    }
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
    next_client: ClientId,
    access: Option<Access>,
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
        os.unset_environment(SECRET_VARIABLE);
        if secret.is_empty() {
            return Err(format!(
                "{SECRET_VARIABLE} is not set: the server only serves the run that started it (the trainer sets a \
                 fresh secret; see docs/protocol.md, Access)"
            ));
        }
        self.access = Some(Access::new(&secret)?);
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
    /// Bytes are collected per client as they arrive and replies leave as each client takes them, so a
    /// client that sends half a frame, or never reads, holds up no one.
    fn serve(&mut self) {
        let mut last_activity = Instant::now();
        loop {
            self.accept_pending();
            self.flush_all();
            self.drop_overdue();
            let Some((client, result)) = self.next_buffered_message() else {
                match self.wait_for_clients() {
                    Some(readable) => {
                        last_activity = Instant::now();
                        for client in readable {
                            self.receive_bytes(client);
                        }
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
                    self.send(client, &error_reply(&reason));
                    continue;
                }
                Err(ProtocolError::Framing(reason)) => {
                    // This stream cannot be resynchronised: say why and drop this client only.
                    let hint = match self.access.as_ref().is_some_and(|a| a.is_authenticated(client)) {
                        true => "",
                        false => " (before a hello with this server's secret, no message may carry arrays)",
                    };
                    self.close_after(client, &error_reply(&format!("{reason}{hint}; closing the connection")));
                    continue;
                }
                Err(ProtocolError::Closed | ProtocolError::Io(_)) => {
                    self.disconnect(client, None);
                    continue;
                }
            };
            let Some(access) = self.access.as_mut() else { return };
            match access.admit(client, &message) {
                Verdict::Pass => {}
                Verdict::Refuse(reply) => {
                    self.send(client, &reply);
                    continue;
                }
                Verdict::Close(reply) => {
                    godot_warn!("PunchTrainingServer: closing client {client}: {}", error_text(&reply));
                    self.close_after(client, &reply);
                    continue;
                }
            }
            if message.message_type() == "hello"
                && let Some(connection) = self.connection(client)
            {
                // Admitted with the secret: it may now send arrays.
                connection.frames.set_payload_limit(usize::MAX);
            }
            let (Some(session), Some(world)) = (self.session.as_mut(), self.world.as_mut()) else {
                return;
            };
            match session.handle(&message, world) {
                Outcome::Reply(reply) => self.send(client, &reply),
                Outcome::Running => {
                    self.running = Some(client);
                    return;
                }
                Outcome::Close(reply) => self.close_after(client, &reply),
            }
        }
    }

    fn connection(&mut self, client: ClientId) -> Option<&mut Connection> {
        self.connections.iter_mut().find(|c| c.id == client)
    }

    /// A complete message that a client ready for requests has already sent, if any.
    fn next_buffered_message(&mut self) -> Option<(ClientId, Result<Message, ProtocolError>)> {
        self.connections
            .iter_mut()
            .filter(|c| c.ready_for_requests())
            .find_map(|c| c.frames.next_message().map(|r| (c.id, r)))
    }

    /// Reads what a readable client has sent (poll said it is readable, so this does not block), within the
    /// memory budget of all connections together.
    fn receive_bytes(&mut self, client: ClientId) {
        let held: usize = self.connections.iter().map(|c| c.frames.buffered_bytes() + c.outbox.len()).sum();
        if held + RECEIVE_CHUNK_BYTES > MEMORY_BUDGET_BYTES {
            let reason =
                format!("the server's memory budget ({MEMORY_BUDGET_BYTES} bytes for all connections) is full");
            self.close_after(client, &error_reply(&format!("{reason}; closing the connection")));
            return;
        }
        let Some(connection) = self.connection(client) else { return };
        match connection.frames.read_available(&mut connection.stream, RECEIVE_CHUNK_BYTES) {
            Ok(0) if connection.frames.buffered_bytes() > 0 && !connection.closing => {
                // The client may have shut only its sending side: it can still read why.
                let reply = error_reply("connection closed inside a message; closing the connection");
                self.close_after(client, &reply);
            }
            Ok(0) => self.disconnect(client, None),
            Ok(_) => {}
            Err(error) if matches!(error.kind(), ErrorKind::Interrupted | ErrorKind::WouldBlock) => {}
            Err(error) => self.disconnect(client, Some(&error.to_string())),
        }
    }

    /// Takes every client waiting in the listen queue, up to `MAX_CONNECTIONS` open at once.
    fn accept_pending(&mut self) {
        let Some(listener) = &self.listener else {
            return;
        };
        loop {
            match listener.accept() {
                Ok((mut stream, _)) => {
                    if self.connections.len() >= MAX_CONNECTIONS {
                        // Best effort, never blocking: the refusal fits in any socket buffer.
                        let refusal = error_reply(&format!("the server has {MAX_CONNECTIONS} connections open"));
                        let _ = stream.set_nonblocking(true).and_then(|()| stream.write(&refusal.encode()));
                        godot_warn!("PunchTrainingServer: refused a connection: {MAX_CONNECTIONS} are open");
                        continue;
                    }
                    if stream.set_nonblocking(true).is_ok() && stream.set_nodelay(true).is_ok() {
                        self.next_client += 1;
                        self.connections.push(Connection {
                            id: self.next_client,
                            stream,
                            frames: FrameReader::with_payload_limit(UNAUTHENTICATED_PAYLOAD_BYTES),
                            outbox: Vec::new(),
                            stalled_since: None,
                            opened: Instant::now(),
                            closing: false,
                        });
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

    /// Closes the clients that broke a time limit: no hello with the secret within `HELLO_TIMEOUT_S`, or a
    /// reply left unread for `UNREAD_REPLY_TIMEOUT_S`.
    fn drop_overdue(&mut self) {
        let access = self.access.as_ref();
        let overdue: Vec<(ClientId, String)> = self
            .connections
            .iter()
            .filter_map(|c| {
                if c.stalled_since.is_some_and(|t| t.elapsed().as_secs_f32() > UNREAD_REPLY_TIMEOUT_S) {
                    Some((c.id, format!("it read none of its reply for {UNREAD_REPLY_TIMEOUT_S} s")))
                } else if !access.is_some_and(|a| a.is_authenticated(c.id))
                    && c.opened.elapsed().as_secs_f32() > HELLO_TIMEOUT_S
                {
                    Some((c.id, format!("no hello with the secret within {HELLO_TIMEOUT_S} s")))
                } else {
                    None
                }
            })
            .collect();
        for (client, reason) in overdue {
            self.disconnect(client, Some(&reason));
        }
    }

    /// Waits up to 20 ms for a client with bytes to read (or a closed one) and for sockets that can take more
    /// of a reply; returns the readable clients, or None when nothing happened. Clients whose reply is still
    /// being sent are not read: their requests wait in their own socket.
    fn wait_for_clients(&mut self) -> Option<Vec<ClientId>> {
        let mut fds: Vec<libc::pollfd> = self
            .connections
            .iter()
            .map(|c| {
                let mut events = if c.ready_for_requests() { libc::POLLIN } else { 0 };
                if !c.outbox.is_empty() {
                    events |= libc::POLLOUT;
                }
                libc::pollfd { fd: c.stream.as_raw_fd(), events, revents: 0 }
            })
            .collect();
        if let Some(listener) = &self.listener {
            fds.push(libc::pollfd { fd: listener.as_raw_fd(), events: libc::POLLIN, revents: 0 });
        }
        // SAFETY: `fds` is a valid array of pollfd for the duration of the call.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, 20) };
        if ready <= 0 {
            return None;
        }
        let readable: Vec<ClientId> = self
            .connections
            .iter()
            .zip(&fds)
            .filter(|(c, fd)| {
                c.ready_for_requests() && fd.revents & (libc::POLLIN | libc::POLLHUP | libc::POLLERR) != 0
            })
            .map(|(c, _)| c.id)
            .collect();
        Some(readable)
    }

    /// Queues a reply and sends what the socket takes now.
    fn send(&mut self, client: ClientId, message: &Message) {
        let Some(connection) = self.connection(client) else { return };
        connection.outbox.extend_from_slice(&message.encode());
        if let Err(error) = connection.flush() {
            self.disconnect(client, Some(&error.to_string()));
        }
    }

    /// Sends a last reply, then closes the connection once the client has taken it (or its time is up).
    fn close_after(&mut self, client: ClientId, message: &Message) {
        self.send(client, message);
        if let Some(connection) = self.connection(client) {
            connection.closing = true;
            connection.frames = FrameReader::with_payload_limit(0);
        }
        if let Some(access) = self.access.as_mut() {
            access.disconnected(client);
        }
        self.flush_all();
    }

    /// Sends what every socket takes now; closes the clients that are gone or done.
    fn flush_all(&mut self) {
        let mut gone = Vec::new();
        for connection in &mut self.connections {
            match connection.flush() {
                Err(error) => gone.push((connection.id, Some(error.to_string()))),
                Ok(()) if connection.closing && connection.outbox.is_empty() => gone.push((connection.id, None)),
                Ok(()) => {}
            }
        }
        for (client, reason) in gone {
            self.disconnect(client, reason.as_deref());
        }
    }

    /// Forgets a client (with the reason, when it was not a clean goodbye, in the log).
    fn disconnect(&mut self, client: ClientId, reason: Option<&str>) {
        let Some(index) = self.connections.iter().position(|c| c.id == client) else { return };
        self.connections.remove(index);
        if let Some(reason) = reason {
            godot_warn!("PunchTrainingServer: closed client {client}: {reason}");
        }
        if let Some(access) = self.access.as_mut() {
            access.disconnected(client);
        }
    }

    fn quit(&mut self, code: i32) {
        self.world = None;
        self.base().get_tree().quit_ex().exit_code(code).done();
    }
}

/// The environment variable that carries the run's secret to the server.
pub const SECRET_VARIABLE: &str = "PUNCH_SERVER_SECRET";

fn error_text(reply: &Message) -> String {
    reply.header.get("message").and_then(|m| m.as_str()).unwrap_or_default().to_string()
}
