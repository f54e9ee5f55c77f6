//! Who may talk to a training server, and who may drive its characters (docs/protocol.md, Access).
//!
//! A server belongs to the run that started it: the trainer gives it a fresh secret (in the environment,
//! never on a command line other users can read), and a connection must say `hello` with that secret before
//! anything else. The server's characters run in lockstep as one episode, so the first connection that
//! resets, steps or rolls out owns all of them until it closes; another connection, even with the secret,
//! cannot touch them meanwhile.

use std::collections::HashSet;

use serde_json::Value;

use crate::training::protocol::{Message, error_reply};

/// A connection's number, unique for the life of the server.
pub type ClientId = u64;

/// What to do with a message before the session sees it.
#[derive(Debug, PartialEq)]
pub enum Verdict {
    /// Hand it to the session.
    Pass,
    /// Answer with this error and go on reading from the client.
    Refuse(Message),
    /// Answer with this error and close the connection.
    Close(Message),
}

/// The server's secret, the connections that proved they know it, and the owner of the characters.
#[derive(Debug)]
pub struct Access {
    secret: String,
    authenticated: HashSet<ClientId>,
    owner: Option<ClientId>,
}

/// Shortest secret a server accepts, bytes.
pub const MIN_SECRET_BYTES: usize = 16;

impl Access {
    /// Access for a server whose run's secret is `secret` (at least `MIN_SECRET_BYTES` long).
    pub fn new(secret: &str) -> Result<Self, String> {
        if secret.len() < MIN_SECRET_BYTES {
            return Err(format!("the server's secret must be at least {MIN_SECRET_BYTES} bytes"));
        }
        Ok(Self { secret: secret.to_string(), authenticated: HashSet::new(), owner: None })
    }

    /// Whether `client` has said hello with the secret (it may then send large messages).
    pub fn is_authenticated(&self, client: ClientId) -> bool {
        self.authenticated.contains(&client)
    }

    /// Checks a message from `client`.
    pub fn admit(&mut self, client: ClientId, message: &Message) -> Verdict {
        match message.message_type() {
            "hello" => {
                let given = message.header.get("secret").and_then(Value::as_str).unwrap_or_default();
                if !same_bytes(given.as_bytes(), self.secret.as_bytes()) {
                    return Verdict::Close(error_reply(
                        "wrong or missing 'secret': this server belongs to the run that started it (the trainer \
                         gives it PUNCH_SERVER_SECRET); closing the connection",
                    ));
                }
                self.authenticated.insert(client);
                Verdict::Pass
            }
            _ if !self.is_authenticated(client) => {
                Verdict::Close(error_reply("say 'hello' with this server's secret first; closing the connection"))
            }
            "reset" | "step" | "rollout" => match self.owner {
                Some(owner) if owner != client => Verdict::Refuse(error_reply(
                    "the characters belong to another connection of this run until it closes (they run as one \
                     episode, so one connection drives them)",
                )),
                _ => {
                    self.owner = Some(client);
                    Verdict::Pass
                }
            },
            _ => Verdict::Pass,
        }
    }

    /// Forgets a closed connection; its characters are free for another one.
    pub fn disconnected(&mut self, client: ClientId) {
        self.authenticated.remove(&client);
        if self.owner == Some(client) {
            self.owner = None;
        }
    }
}

/// Overwrites the value of the environment variable `name` where this process received it, so that
/// `/proc/PID/environ` (which shows the environment a process started with, whatever it unset since) no
/// longer holds the run's secret. Call it once the value has been read; returns whether the variable was
/// there. Linux with glibc only (the training server's platform); elsewhere it does nothing.
pub fn scrub_environment_variable(name: &str) -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let prefix = format!("{name}=");
        let mut found = false;
        // SAFETY: `environ` is the process's null-terminated array of NUL-terminated strings, which point into
        // the memory the kernel set up at start (what /proc/PID/environ reads) for variables nobody set since.
        // The bytes are overwritten in place, never past their terminating NUL, and no pointer is kept.
        unsafe {
            let mut entry = libc::environ;
            while !entry.is_null() && !(*entry).is_null() {
                let text = std::ffi::CStr::from_ptr(*entry).to_bytes();
                if text.starts_with(prefix.as_bytes()) {
                    let value = (*entry).cast::<u8>().add(prefix.len());
                    for offset in 0..text.len() - prefix.len() {
                        value.add(offset).write_volatile(0);
                    }
                    found = true;
                }
                entry = entry.add(1);
            }
        }
        found
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        let _ = name;
        false
    }
}

/// Compares in time independent of where the bytes differ, so a local user cannot find the secret byte by
/// byte from reply times.
fn same_bytes(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |diff, (x, y)| diff | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    const SECRET: &str = "0123456789abcdef0123";

    fn message(fields: Value) -> Message {
        let Value::Object(header) = fields else { unreachable!() };
        Message { header, arrays: Vec::new() }
    }

    fn hello(secret: &str) -> Message {
        message(
            json!({"type": "hello", "protocol_version": crate::training::protocol::PROTOCOL_VERSION, "secret": secret}),
        )
    }

    #[test]
    fn a_short_secret_is_refused() {
        assert!(Access::new("short").is_err());
    }

    #[test]
    fn nothing_passes_before_a_hello_with_the_secret() {
        let mut access = Access::new(SECRET).expect("secret");
        assert!(matches!(access.admit(1, &message(json!({"type": "reset"}))), Verdict::Close(_)));
        assert!(matches!(access.admit(1, &hello("wrong-wrong-wrong-wrong")), Verdict::Close(_)));
        assert!(matches!(access.admit(1, &message(json!({"type": "hello"}))), Verdict::Close(_)));
        assert!(!access.is_authenticated(1));
        assert_eq!(access.admit(1, &hello(SECRET)), Verdict::Pass);
        assert!(access.is_authenticated(1));
        assert_eq!(access.admit(1, &message(json!({"type": "reset"}))), Verdict::Pass);
    }

    #[test]
    fn the_first_to_drive_owns_the_characters_until_it_closes() {
        let mut access = Access::new(SECRET).expect("secret");
        for client in [1, 2] {
            assert_eq!(access.admit(client, &hello(SECRET)), Verdict::Pass);
        }
        assert_eq!(access.admit(1, &message(json!({"type": "reset"}))), Verdict::Pass);
        for kind in ["reset", "step", "rollout"] {
            assert!(matches!(access.admit(2, &message(json!({"type": kind}))), Verdict::Refuse(_)), "{kind}");
        }
        assert_eq!(access.admit(1, &message(json!({"type": "step"}))), Verdict::Pass);
        access.disconnected(1);
        assert_eq!(access.admit(2, &message(json!({"type": "rollout"}))), Verdict::Pass);
        assert!(matches!(access.admit(1, &message(json!({"type": "reset"}))), Verdict::Close(_)), "forgotten");
    }

    #[test]
    fn comparison_is_exact() {
        assert!(same_bytes(b"abc", b"abc"));
        assert!(!same_bytes(b"abc", b"abd"));
        assert!(!same_bytes(b"abc", b"abcd"));
    }
}
