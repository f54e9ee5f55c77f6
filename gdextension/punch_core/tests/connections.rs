//! The training server's connections on real loopback sockets: clients that never read, send half a frame,
//! fill the memory budget, come one too many or never say hello hold up no one else, and each is told why it
//! is closed.
#![cfg(unix)]

use std::io::{Read, Write};
use std::net::{Shutdown, TcpStream};
use std::time::{Duration, Instant};

use punch_core::training::connections::{Connections, Limits};
use punch_core::training::protocol::{Array, KEPT_BUFFER_BYTES, Message, PROTOCOL_VERSION};
use serde_json::json;

const SECRET: &str = "0123456789abcdef-test";

fn quick_limits() -> Limits {
    Limits {
        hello_timeout: Duration::from_millis(300),
        unread_reply_timeout: Duration::from_millis(300),
        poll_wait: Duration::from_millis(5),
        ..Limits::default()
    }
}

fn server(limits: Limits) -> Connections {
    Connections::listen(0, SECRET, limits).expect("listens on loopback")
}

fn client(server: &Connections) -> TcpStream {
    let stream = TcpStream::connect(("127.0.0.1", server.port())).expect("connects");
    stream.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
    stream
}

fn hello() -> Message {
    Message::new("hello").with("protocol_version", json!(PROTOCOL_VERSION)).with("secret", json!(SECRET))
}

/// Polls the server until it hands over a request (at most two seconds).
fn next_request(server: &mut Connections) -> (u64, Message) {
    let deadline = Instant::now() + Duration::from_secs(2);
    while Instant::now() < deadline {
        if let Some(request) = server.next_request() {
            return request;
        }
    }
    panic!("no request arrived; notices: {:?}", server.take_notices());
}

/// Polls the server for `duration` (every request that comes is dropped unanswered).
fn poll_for(server: &mut Connections, duration: Duration) -> Vec<String> {
    let deadline = Instant::now() + duration;
    while Instant::now() < deadline {
        server.next_request();
    }
    server.take_notices()
}

/// Says hello and returns the server's id of this client.
fn authenticated(server: &mut Connections) -> (TcpStream, u64) {
    let mut stream = client(server);
    hello().write_to(&mut stream).expect("sends hello");
    let (id, message) = next_request(server);
    assert_eq!(message.message_type(), "hello");
    (stream, id)
}

/// Reads replies until the server closes the stream; returns their error messages.
fn errors_until_closed(stream: &mut TcpStream) -> Vec<String> {
    let mut errors = Vec::new();
    while let Ok(message) = Message::read_from(stream) {
        errors.push(message.header.get("message").and_then(|m| m.as_str()).unwrap_or_default().to_string());
    }
    errors
}

#[test]
fn a_client_that_never_reads_is_closed_in_time_and_holds_up_no_one() {
    let mut server = server(quick_limits());
    let (mut sleeper, sleeper_id) = authenticated(&mut server);
    // A reply far larger than the sockets' buffers: the sleeper never reads it.
    let big = Message::new("rollout_done").with_array(Array::new("features", vec![4_000_000], vec![0.5; 4_000_000]));
    server.send(sleeper_id, &big);
    let (mut worker, worker_id) = authenticated(&mut server);
    Message::new("ping").write_to(&mut worker).expect("sends");
    let (id, message) = next_request(&mut server);
    assert_eq!((id, message.message_type()), (worker_id, "ping"), "served while the sleeper's reply waits");
    let notices = poll_for(&mut server, Duration::from_millis(600));
    assert!(
        notices.iter().any(|n| n.contains(&format!("client {sleeper_id}")) && n.contains("read none")),
        "{notices:?}"
    );
    assert_eq!(server.count(), 1, "only the worker is left");
    let mut bytes = Vec::new();
    sleeper.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
    let _ = sleeper.read_to_end(&mut bytes);
    assert!(bytes.len() < big.encode().len(), "the sleeper's connection ended before its whole reply");
}

#[test]
fn half_a_frame_holds_up_no_one_and_a_stream_closed_inside_a_message_is_told_so() {
    let mut server = server(quick_limits());
    let (mut half, _) = authenticated(&mut server);
    let frame = Message::new("step").with_array(Array::new("actions", vec![1, 10], vec![0.0; 10])).encode();
    half.write_all(&frame[..frame.len() / 2]).expect("sends half");
    let (mut other, other_id) = authenticated(&mut server);
    Message::new("ping").write_to(&mut other).expect("sends");
    assert_eq!(next_request(&mut server).0, other_id);
    half.shutdown(Shutdown::Write).expect("half-closes");
    poll_for(&mut server, Duration::from_millis(100));
    let errors = errors_until_closed(&mut half);
    assert!(errors.iter().any(|e| e.contains("closed inside a message")), "{errors:?}");
}

#[test]
fn the_memory_budget_closes_the_connection_that_would_go_over_it() {
    let limits = Limits { memory_budget_bytes: 256 * 1024, receive_chunk_bytes: 64 * 1024, ..quick_limits() };
    let mut server = server(limits);
    let (mut greedy, _) = authenticated(&mut server);
    let (mut modest, modest_id) = authenticated(&mut server);
    // One message of 2 MB: the server would have to hold all of it before handling it.
    let frame =
        Message::new("step").with_array(Array::new("actions", vec![512 * 1024], vec![0.0; 512 * 1024])).encode();
    let writer = std::thread::spawn(move || {
        let _ = greedy.write_all(&frame);
        errors_until_closed(&mut greedy)
    });
    let notices = poll_for(&mut server, Duration::from_millis(500));
    let errors = writer.join().expect("writer thread");
    assert!(errors.iter().any(|e| e.contains("memory budget")), "{errors:?} {notices:?}");
    Message::new("ping").write_to(&mut modest).expect("sends");
    assert_eq!(next_request(&mut server).0, modest_id, "the other client is still served");
}

#[test]
fn a_hello_with_the_secret_over_the_limit_is_told_the_server_is_busy() {
    let mut server = server(Limits { max_connections: 2, ..quick_limits() });
    let _first = authenticated(&mut server);
    let _second = authenticated(&mut server);
    let mut third = client(&server);
    hello().write_to(&mut third).expect("sends hello");
    let notices = poll_for(&mut server, Duration::from_millis(50));
    assert!(notices.iter().any(|n| n.contains("busy")), "{notices:?}");
    let errors = errors_until_closed(&mut third);
    assert_eq!(errors, ["the server is busy: 2 connections of this run are open; closing the connection"]);
    assert_eq!(server.count(), 2);
}

#[test]
fn connections_held_without_a_hello_do_not_keep_the_runs_client_out() {
    let mut server = server(Limits { max_connections: 2, max_waiting: 4, ..quick_limits() });
    // Outsiders hold twice every slot there is, saying nothing.
    let mut held: Vec<TcpStream> = (0..8).map(|_| client(&server)).collect();
    poll_for(&mut server, Duration::from_millis(50));
    assert_eq!(server.count(), 4, "at most max_waiting connections wait for their hello");
    let (_run, _) = authenticated(&mut server);
    let errors: Vec<String> = held.iter_mut().take(5).flat_map(errors_until_closed).collect();
    assert!(errors.iter().all(|e| e.starts_with("the server is busy: 4 connections are waiting")), "{errors:?}");
    assert_eq!(errors.len(), 5, "the oldest ones were closed, each told why: {errors:?}");
}

#[test]
fn a_flood_of_refused_clients_logs_a_bounded_number_of_lines() {
    let limits = Limits { log_lines_per_interval: 5, log_interval: Duration::from_millis(400), ..quick_limits() };
    let mut server = server(limits);
    let mut notices = Vec::new();
    for _ in 0..60 {
        let mut intruder = client(&server);
        Message::new("hello")
            .with("protocol_version", json!(PROTOCOL_VERSION))
            .with("secret", json!("wrong-wrong-wrong-wrong"))
            .write_to(&mut intruder)
            .expect("sends");
        notices.extend(poll_for(&mut server, Duration::from_millis(2)));
    }
    notices.extend(poll_for(&mut server, Duration::from_millis(500)));
    assert!(notices.len() <= 5 * 3 + 3, "{} lines: {notices:?}", notices.len());
    assert!(notices.iter().any(|n| n.contains("more such lines")), "{notices:?}");
    let (_run, _) = authenticated(&mut server);
}

#[test]
fn a_connection_that_says_no_hello_in_time_or_speaks_first_is_closed() {
    let mut server = server(quick_limits());
    let mut silent = client(&server);
    let notices = poll_for(&mut server, Duration::from_millis(500));
    assert!(notices.iter().any(|n| n.contains("no hello")), "{notices:?}");
    assert!(errors_until_closed(&mut silent).is_empty(), "closed without a word: it said nothing either");
    let mut rude = client(&server);
    Message::new("reset").write_to(&mut rude).expect("sends");
    poll_for(&mut server, Duration::from_millis(50));
    let errors = errors_until_closed(&mut rude);
    assert!(errors.iter().any(|e| e.contains("hello")), "{errors:?}");
    let mut arrays_first = client(&server);
    let step = Message::new("hello").with_array(Array::new("actions", vec![10], vec![0.0; 10]));
    step.write_to(&mut arrays_first).expect("sends");
    poll_for(&mut server, Duration::from_millis(50));
    let errors = errors_until_closed(&mut arrays_first);
    assert!(errors.iter().any(|e| e.contains("no message may carry arrays")), "{errors:?}");
    assert_eq!(server.count(), 0);
}

#[test]
fn a_request_waits_while_its_clients_reply_is_unsent_then_comes() {
    let mut server = server(Limits { unread_reply_timeout: Duration::from_secs(5), ..quick_limits() });
    let (mut slow, slow_id) = authenticated(&mut server);
    let big = Message::new("rollout_done").with_array(Array::new("features", vec![4_000_000], vec![0.5; 4_000_000]));
    server.send(slow_id, &big);
    Message::new("ping").write_to(&mut slow).expect("sends while its reply waits");
    assert!(poll_for(&mut server, Duration::from_millis(100)).is_empty());
    let reader = std::thread::spawn(move || {
        let reply = Message::read_from(&mut slow).expect("the whole reply");
        (slow, reply.message_type().to_string())
    });
    let (id, message) = next_request(&mut server);
    assert_eq!((id, message.message_type()), (slow_id, "ping"), "its request comes once its reply is taken");
    let (_slow, kind) = reader.join().expect("reader thread");
    assert_eq!(kind, "rollout_done");
}

#[test]
fn the_memory_of_large_messages_goes_back_once_they_are_handled() {
    let mut server = server(Limits { unread_reply_timeout: Duration::from_secs(5), ..quick_limits() });
    let mut clients: Vec<(TcpStream, u64)> = (0..3).map(|_| authenticated(&mut server)).collect();
    // Each sends a request of 4 MB and gets a reply of 4 MB (a message type any connection may send): the
    // budget must count what the server keeps, not what it is using.
    let request = Message::new("echo").with_array(Array::new("actions", vec![1_000_000], vec![0.25; 1_000_000]));
    let readers: Vec<_> = clients
        .drain(..)
        .map(|(mut stream, id)| {
            let request = request.clone();
            let thread = std::thread::spawn(move || {
                request.write_to(&mut stream).expect("sends");
                let reply = Message::read_from(&mut stream).expect("the whole reply");
                (stream, reply.message_type().to_string())
            });
            (thread, id)
        })
        .collect();
    for _ in 0..readers.len() {
        let (id, message) = next_request(&mut server);
        assert_eq!(message.message_type(), "echo");
        server.send(id, &message.clone().with("type", json!("echo_done")));
    }
    // Serve until every client has its whole reply (the last bytes of a reply may go out after what the server
    // holds is already under the budget, and a client left waiting for them would time out), then until the
    // buffers are given back.
    let deadline = Instant::now() + Duration::from_secs(5);
    while (readers.iter().any(|(thread, _)| !thread.is_finished()) || server.held_bytes() > 3 * 2 * KEPT_BUFFER_BYTES)
        && Instant::now() < deadline
    {
        server.next_request();
    }
    for (thread, _) in readers {
        assert_eq!(thread.join().expect("reader").1, "echo_done");
    }
    server.flush_all();
    assert!(
        server.held_bytes() <= 3 * 2 * KEPT_BUFFER_BYTES,
        "kept {} bytes after 24 MB went through",
        server.held_bytes()
    );
}
