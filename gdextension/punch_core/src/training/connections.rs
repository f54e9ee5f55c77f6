//! The training server's connections: a non-blocking TCP listener on loopback and its clients, multiplexed
//! with poll(2) on the one thread that also steps physics.
//!
//! Bytes are collected per client as they arrive and replies leave as each client takes them, so a client
//! that sends half a frame, or never reads, holds up no one. Every client must say hello with the run's
//! secret (`access`); the connections together hold at most a memory budget; a connection that says no
//! hello in time, or leaves a reply unread too long, is closed. The session (what a request does) is the
//! caller's: `next_request` hands over each admitted request, and `send` or `close_after` answers it.

use std::io::{ErrorKind, Write};
use std::net::{TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

use crate::training::access::{Access, ClientId, Verdict};
use crate::training::log_budget::LogBudget;
use crate::training::protocol::{FrameReader, Message, ProtocolError, error_reply, release_spare};

/// The server's limits on its clients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Connections of this run (that said hello with the secret) at most; a hello with the secret over it is
    /// answered that the server is busy, and closed.
    pub max_connections: usize,
    /// Connections that have not yet said hello with the secret, at most. A new connection over it closes the
    /// oldest of them (told that the server is busy): whoever holds them, the run's own client, which says
    /// hello at once, still gets in.
    pub max_waiting: usize,
    /// Lines about clients (refusals, closures) the server's log takes at most per `log_interval`; the rest
    /// are counted in one line per interval, so that no one can flood the log.
    pub log_lines_per_interval: usize,
    /// See `log_lines_per_interval`.
    pub log_interval: Duration,
    /// Bytes all connections together may keep (their buffers' capacity: received and not yet handled, or to
    /// be sent, half-sent frames included); a connection whose next read would go over it is closed.
    pub memory_budget_bytes: usize,
    /// Bytes read from a client at most per poll round (a rollout request of 64 characters is about 26 kB).
    pub receive_chunk_bytes: usize,
    /// Time a new connection has to say hello with the secret.
    pub hello_timeout: Duration,
    /// Time a reply may wait with none of it read by its client; then the client is closed. While a
    /// connection's reply waits, its further requests are not read (a client that never reads only fills
    /// its own socket).
    pub unread_reply_timeout: Duration,
    /// Longest wait for a client in one `next_request`.
    pub poll_wait: Duration,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_connections: 8,
            max_waiting: 16,
            log_lines_per_interval: 20,
            log_interval: Duration::from_secs(60),
            memory_budget_bytes: 512 * 1024 * 1024,
            receive_chunk_bytes: 64 * 1024,
            hello_timeout: Duration::from_secs(10),
            unread_reply_timeout: Duration::from_secs(60),
            poll_wait: Duration::from_millis(20),
        }
    }
}

/// Largest payload from a connection that has not yet said hello with the secret (a hello has none).
const UNAUTHENTICATED_PAYLOAD_BYTES: usize = 0;

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
                    release_spare(&mut self.outbox);
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

    /// Memory it keeps, bytes.
    fn held_bytes(&self) -> usize {
        self.frames.held_bytes() + self.outbox.capacity()
    }

    /// Whether its next message may be handled: nothing of an earlier reply is waiting.
    fn ready_for_requests(&self) -> bool {
        self.outbox.is_empty() && !self.closing
    }
}

/// The listener and every open connection.
pub struct Connections {
    listener: TcpListener,
    connections: Vec<Connection>,
    next_client: ClientId,
    access: Access,
    limits: Limits,
    last_activity: Instant,
    /// What happened to clients that the server's log should say (refusals, closures and why).
    notices: Vec<String>,
    /// How many of those lines the log takes (outsiders can cause them).
    log_budget: LogBudget,
}

impl Connections {
    /// Listens on 127.0.0.1:`port` (0: a free port) for the run whose secret is `secret`.
    pub fn listen(port: u16, secret: &str, limits: Limits) -> Result<Self, String> {
        let access = Access::new(secret)?;
        let listener =
            TcpListener::bind(("127.0.0.1", port)).map_err(|e| format!("cannot listen on port {port}: {e}"))?;
        listener.set_nonblocking(true).map_err(|e| e.to_string())?;
        Ok(Self {
            listener,
            connections: Vec::new(),
            next_client: 0,
            access,
            limits,
            last_activity: Instant::now(),
            notices: Vec::new(),
            log_budget: LogBudget::new(limits.log_lines_per_interval, limits.log_interval, Instant::now()),
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.listener.local_addr().map_or(0, |address| address.port())
    }

    /// Open connections.
    pub fn count(&self) -> usize {
        self.connections.len()
    }

    /// Memory all connections keep together, bytes (what the memory budget limits).
    pub fn held_bytes(&self) -> usize {
        self.connections.iter().map(Connection::held_bytes).sum()
    }

    /// Time since a client last sent something (or since `note_activity`).
    pub fn idle_for(&self) -> Duration {
        self.last_activity.elapsed()
    }

    /// Counts now as activity (the server was busy with a request).
    pub fn note_activity(&mut self) {
        self.last_activity = Instant::now();
    }

    /// What happened to clients since the last call, one line each, for the server's log (within the log
    /// budget of `Limits::log_lines_per_interval`, with a line that counts what it left out).
    pub fn take_notices(&mut self) -> Vec<String> {
        self.notices.extend(self.log_budget.summary(Instant::now()));
        std::mem::take(&mut self.notices)
    }

    fn notice(&mut self, line: String) {
        let lines = self.log_budget.admit(line, Instant::now());
        self.notices.extend(lines);
    }

    /// The next request a client sent and `access` admitted, waiting at most `Limits::poll_wait` for one to
    /// arrive. Meanwhile it accepts new clients, sends what sockets take, closes overdue clients and answers
    /// malformed or refused messages itself.
    pub fn next_request(&mut self) -> Option<(ClientId, Message)> {
        loop {
            self.accept_pending();
            self.flush_all();
            self.drop_overdue();
            let Some((client, result)) = self.next_buffered_message() else {
                let readable = self.wait_for_clients()?;
                self.last_activity = Instant::now();
                for client in readable {
                    self.receive_bytes(client);
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
                    let hint = match self.access.is_authenticated(client) {
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
            if message.message_type() == "hello" && self.is_full_with_run_clients(client) {
                let limit = self.limits.max_connections;
                let reply = error_reply(&format!(
                    "the server is busy: {limit} connections of this run are open; closing the connection"
                ));
                self.notice(format!("closing client {client}: {}", error_text(&reply)));
                self.close_after(client, &reply);
                continue;
            }
            match self.access.admit(client, &message) {
                Verdict::Pass => {}
                Verdict::Refuse(reply) => {
                    self.send(client, &reply);
                    continue;
                }
                Verdict::Close(reply) => {
                    self.notice(format!("closing client {client}: {}", error_text(&reply)));
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
            self.last_activity = Instant::now();
            return Some((client, message));
        }
    }

    /// Queues a reply and sends what the socket takes now.
    pub fn send(&mut self, client: ClientId, message: &Message) {
        let Some(connection) = self.connection(client) else { return };
        connection.outbox.extend_from_slice(&message.encode());
        if let Err(error) = connection.flush() {
            self.disconnect(client, Some(&error.to_string()));
        }
    }

    /// Sends a last reply, then closes the connection once the client has taken it (or its time is up).
    pub fn close_after(&mut self, client: ClientId, message: &Message) {
        self.send(client, message);
        if let Some(connection) = self.connection(client) {
            connection.closing = true;
            connection.frames = FrameReader::with_payload_limit(0);
        }
        self.access.disconnected(client);
        self.flush_all();
    }

    /// Sends what every socket takes now; closes the clients that are gone or done.
    pub fn flush_all(&mut self) {
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

    /// Whether `client`, not yet admitted, would be one connection of this run too many.
    fn is_full_with_run_clients(&self, client: ClientId) -> bool {
        !self.access.is_authenticated(client)
            && self.connections.iter().filter(|c| self.access.is_authenticated(c.id)).count()
                >= self.limits.max_connections
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
        let (chunk, budget) = (self.limits.receive_chunk_bytes, self.limits.memory_budget_bytes);
        let held_elsewhere: usize =
            self.connections.iter().filter(|c| c.id != client).map(Connection::held_bytes).sum();
        let Some(connection) = self.connection(client) else { return };
        // After the read its buffer may keep up to twice what it then holds (a Vec doubles as it grows).
        let after_read = connection.frames.held_bytes().max(2 * (connection.frames.buffered_bytes() + chunk));
        if held_elsewhere + after_read + connection.outbox.capacity() > budget {
            let reason = format!("the server's memory budget ({budget} bytes for all connections) is full");
            self.close_after(client, &error_reply(&format!("{reason}; closing the connection")));
            return;
        }
        let Some(connection) = self.connection(client) else { return };
        match connection.frames.read_available(&mut connection.stream, chunk) {
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

    /// Takes every client waiting in the listen queue; with `Limits::max_waiting` connections waiting to say
    /// hello, each new one closes the oldest of those.
    fn accept_pending(&mut self) {
        loop {
            match self.listener.accept() {
                Ok((stream, _)) => {
                    self.make_room_for_a_new_connection();
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
                    self.notice(format!("accept failed: {error}"));
                    return;
                }
            }
        }
    }

    /// Closes the oldest connection not yet admitted with the secret while `Limits::max_waiting` are open: the
    /// run's own client says hello as soon as it connects, so holding connections keeps no one out.
    fn make_room_for_a_new_connection(&mut self) {
        let limit = self.limits.max_waiting;
        let waiting = self.connections.iter().filter(|c| !self.access.is_authenticated(c.id));
        if waiting.clone().count() < limit {
            return;
        }
        let Some(oldest) = waiting.min_by_key(|c| (c.opened, c.id)).map(|c| c.id) else { return };
        let refusal = error_reply(&format!(
            "the server is busy: {limit} connections are waiting to say hello with the secret; closing the oldest"
        ));
        if let Some(connection) = self.connection(oldest) {
            // Best effort, never blocking: the refusal fits in any socket buffer.
            let _ = connection.stream.write(&refusal.encode());
        }
        self.disconnect(oldest, Some(&format!("{limit} connections were waiting to say hello; it was the oldest")));
    }

    /// Closes the clients that broke a time limit: no hello with the secret in time, or a reply left unread
    /// too long.
    fn drop_overdue(&mut self) {
        let (hello, unread) = (self.limits.hello_timeout, self.limits.unread_reply_timeout);
        let overdue: Vec<(ClientId, String)> = self
            .connections
            .iter()
            .filter_map(|c| {
                if c.stalled_since.is_some_and(|t| t.elapsed() > unread) {
                    Some((c.id, format!("it read none of its reply for {} s", unread.as_secs_f32())))
                } else if !self.access.is_authenticated(c.id) && !c.closing && c.opened.elapsed() > hello {
                    Some((c.id, format!("no hello with the secret within {} s", hello.as_secs_f32())))
                } else {
                    None
                }
            })
            .collect();
        for (client, reason) in overdue {
            self.disconnect(client, Some(&reason));
        }
    }

    /// Waits up to `Limits::poll_wait` for a client with bytes to read (or a closed one) and for sockets that
    /// can take more of a reply; returns the readable clients, or None when nothing happened. Clients whose
    /// reply is still being sent are not read: their requests wait in their own socket.
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
        fds.push(libc::pollfd { fd: self.listener.as_raw_fd(), events: libc::POLLIN, revents: 0 });
        let wait_ms = self.limits.poll_wait.as_millis().min(i32::MAX as u128) as i32;
        // SAFETY: `fds` is a valid array of pollfd for the duration of the call.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, wait_ms) };
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

    /// Forgets a client (with the reason, when it was not a clean goodbye, in the notices).
    fn disconnect(&mut self, client: ClientId, reason: Option<&str>) {
        let Some(index) = self.connections.iter().position(|c| c.id == client) else { return };
        self.connections.remove(index);
        if let Some(reason) = reason {
            self.notice(format!("closed client {client}: {reason}"));
        }
        self.access.disconnected(client);
    }
}

fn error_text(reply: &Message) -> String {
    reply.header.get("message").and_then(|m| m.as_str()).unwrap_or_default().to_string()
}
