//! The run's secret leaves what /proc/PID/environ shows: a child process (this test binary again) receives a
//! secret in its environment, scrubs it, and the parent reads the child's /proc entry.
#![cfg(all(target_os = "linux", target_env = "gnu"))]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use punch_core::training::access::scrub_environment_variable;

const SECRET: &str = "9f8e7d6c5b4a39281706f5e4d3c2b1a0";
/// Set in the child only: it then scrubs and waits to be read.
const CHILD: &str = "PUNCH_TEST_SCRUB_CHILD";

#[test]
fn a_scrubbed_variable_is_gone_from_proc_environ() {
    if std::env::var_os(CHILD).is_some() {
        // The child's half: scrub, say so, and wait for the parent to read /proc.
        assert!(scrub_environment_variable("PUNCH_SERVER_SECRET"));
        assert!(!scrub_environment_variable("PUNCH_NO_SUCH_VARIABLE"));
        println!("SCRUBBED");
        std::thread::sleep(std::time::Duration::from_secs(20));
        return;
    }
    let mut child = Command::new(std::env::current_exe().expect("this test binary"))
        .args(["--exact", "a_scrubbed_variable_is_gone_from_proc_environ", "--nocapture", "--test-threads=1"])
        .env(CHILD, "1")
        .env("PUNCH_SERVER_SECRET", SECRET)
        .stdout(Stdio::piped())
        .spawn()
        .expect("starts the child");
    let environ = format!("/proc/{}/environ", child.id());
    let before = std::fs::read(&environ).expect("readable by the same user");
    let mut lines = BufReader::new(child.stdout.take().expect("piped")).lines();
    let said = lines.find(|line| line.as_deref().is_ok_and(|l| l.contains("SCRUBBED")));
    let after = std::fs::read(&environ).expect("readable by the same user");
    child.kill().ok();
    child.wait().ok();
    assert!(said.is_some(), "the child scrubbed");
    let holds = |bytes: &[u8]| bytes.windows(SECRET.len()).any(|w| w == SECRET.as_bytes());
    assert!(holds(&before) || !holds(&after), "the secret was there at start (or the child was already done)");
    assert!(!holds(&after), "the secret is still in /proc/PID/environ");
    assert!(after.windows(20).any(|w| w == b"PUNCH_SERVER_SECRET="), "the name stays, with its value zeroed");
}
