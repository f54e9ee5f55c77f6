"""Hostile input to the real training server: each bad message gets a clear error reply and the server
goes on serving (a broken frame closes that connection only; a new one is served)."""

import socket
import struct
from pathlib import Path

import numpy as np
import pytest

from punch_trainer.sim.protocol import PROTOCOL_VERSION, Message, ServerError, hello_message, receive
from punch_trainer.sim.server import TrainingServer

pytestmark = pytest.mark.godot


@pytest.fixture(scope="module")
def server():
    with TrainingServer(2) as server:
        yield server


def connect(server: TrainingServer) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", server.port), timeout=30)
    return sock


def still_serving(server: TrainingServer) -> None:
    reply = server.reset()
    assert reply.type == "reset_done"
    assert server.step(np.zeros((2, 10))).type == "step_done"


@pytest.mark.parametrize("fields, arrays, expected", [
    ({"protocol_version": 99}, {}, "protocol version 99"),
    ({}, {}, "protocol_version"),
])
def test_wrong_hello_is_refused(server, fields, arrays, expected):
    with pytest.raises(ServerError, match=expected):
        server.request(Message("hello", {**fields, "secret": server.secret}, arrays))
    still_serving(server)


@pytest.mark.parametrize("actions, expected", [
    (np.zeros((2, 9)), r"shape \[2, 9\], expected \[2, 10\]"),
    (np.zeros((3, 10)), r"shape \[3, 10\]"),
    (np.full((2, 10), np.nan), "non-finite"),
    (np.full((2, 10), np.inf), "non-finite"),
])
def test_bad_actions_are_refused(server, actions, expected):
    server.reset()
    with pytest.raises(ServerError, match=expected):
        server.step(actions)
    still_serving(server)


@pytest.mark.parametrize("message, expected", [
    (Message("dance"), "unknown message type 'dance'"),
    (Message("reset", {"frames": 7}), "multiple of the decision period"),
    (Message("reset", {"frames": -5}), "'frames' must be an integer"),
    (Message("reset", {"bags": {"distance_m": 99}}), "out of range"),
    (Message("reset", {"bags": [{}]}), "lists 1 placements for 2 slots"),
    (Message("rollout", arrays={"actions": np.zeros((2, 0, 10))}), "at least one decision"),
])
def test_bad_requests_are_refused(server, message, expected):
    with pytest.raises(ServerError, match=expected):
        server.request(message)
    still_serving(server)


def test_step_after_the_episode_is_refused(server):
    server.reset(frames=10)
    server.step(np.zeros((2, 10)))
    server.step(np.zeros((2, 10)))
    with pytest.raises(ServerError, match="episode is over"):
        server.step(np.zeros((2, 10)))
    still_serving(server)


@pytest.mark.parametrize("garbage", [
    b"\x00" * 8,                                    # zero-length header
    struct.pack("<II", 0xFFFFFFFF, 0),              # huge header length
    struct.pack("<II", 10, 0x7FFFFFFF),             # huge payload length
    struct.pack("<II", 5, 3) + b"hello",            # payload not a multiple of 4
    struct.pack("<II", 10, 2**31),                  # a payload over the limit (a multiple of 4)
    struct.pack("<II", 10, 200 * 2**20) + b"{" * 10 + b"\0" * 65536,  # half of a 200 MB frame, before a hello
])
def test_broken_frames_get_an_error_and_the_server_serves_the_next_client(server, garbage):
    with connect(server) as intruder:
        intruder.sendall(garbage)
        with pytest.raises(ServerError, match="closing the connection"):
            receive(intruder)
    still_serving(server)


def test_garbage_json_gets_an_error_on_a_living_connection(server):
    with connect(server) as client:
        header = b"{not json"
        client.sendall(struct.pack("<II", len(header), 0) + header)
        with pytest.raises(ServerError, match="not JSON"):
            receive(client)
        client.sendall(hello_message(server.secret).encode())
        assert receive(client).type == "hello"
    still_serving(server)


def test_handshake_describes_the_spec(server):
    info = server.info
    assert info.slot_count == 2 and info.decision_period == 5 and info.physics_hz == 120
    assert len(info.action_names) == 10 and len(info.observation_names) == 54
    assert len(info.spec_hash) == 16 and info.spec_version >= 1
    assert "exploit_flags" in info.feature_names


def authenticated(server: TrainingServer) -> socket.socket:
    client = connect(server)
    client.sendall(hello_message(server.secret).encode())
    assert receive(client).type == "hello"
    return client


@pytest.mark.parametrize("hello", [
    Message("hello", {"protocol_version": PROTOCOL_VERSION}),
    Message("hello", {"protocol_version": PROTOCOL_VERSION, "secret": "0" * 32}),
])
def test_a_client_without_the_secret_is_refused_and_closed(server, hello):
    server.reset()
    for first in [hello, Message("reset"), Message("rollout", arrays={"actions": np.zeros((2, 10, 10))})]:
        with connect(server) as intruder:
            intruder.sendall(first.encode() + Message("step", arrays={"actions": np.zeros((2, 10))}).encode())
            with pytest.raises(ServerError, match="secret"):
                receive(intruder)
            assert intruder.recv(1) == b"", "closed after the refusal: the step behind it is never run"
    # The trainer's episode went on untouched: its next step is the episode's first.
    assert server.step(np.zeros((2, 10))).type == "step_done"
    still_serving(server)


def test_the_secret_is_not_left_where_other_processes_of_the_user_can_read_it(server):
    """The server's initial environment (/proc/PID/environ, readable by the same user) no longer holds it."""
    environ = Path(f"/proc/{server.pid}/environ").read_bytes()
    assert server.secret.encode() not in environ
    assert server.secret not in Path(f"/proc/{server.pid}/cmdline").read_text(errors="replace")
    still_serving(server)


def test_a_second_client_with_the_secret_cannot_touch_the_first_clients_characters(server):
    first = server.reset()
    with authenticated(server) as other:
        for message in [Message("reset"), Message("step", arrays={"actions": np.ones((2, 10))}),
                        Message("rollout", arrays={"actions": np.ones((2, 10, 10))})]:
            other.sendall(message.encode())
            with pytest.raises(ServerError, match="belong to another connection"):
                receive(other)
        # The first client's episode is exactly where it was: the same step gives the same features as on a
        # fresh reset.
        after_intrusion = server.step(np.full((2, 10), 0.1))
    server.reset()
    undisturbed = server.step(np.full((2, 10), 0.1))
    np.testing.assert_array_equal(after_intrusion.arrays["features"], undisturbed.arrays["features"])
    assert first.type == "reset_done"


def test_a_client_that_never_reads_its_replies_stalls_no_one(server):
    with authenticated(server) as flooder:
        flooder.setblocking(False)
        request = hello_message(server.secret).encode()
        sent = 0
        try:
            for _ in range(4000):
                flooder.send(request)
                sent += 1
        except BlockingIOError:
            pass  # the server stopped reading it: its own socket is full
        assert sent > 100
        # Never reading: the server's writes to it would block; the trainer is served at once all the same.
        server._socket.settimeout(10)
        try:
            for _ in range(3):
                still_serving(server)
        finally:
            server._socket.settimeout(server.reply_timeout_s)


def test_connections_are_capped_and_half_sent_frames_do_not_pile_up(server):
    clients = [connect(server) for _ in range(12)]
    try:
        refused = 0
        for client in clients:
            client.sendall(struct.pack("<II", 10, 4096) + b"{")  # half a frame each
            client.settimeout(1)
            try:
                receive(client)
            except ServerError as error:
                assert "connections open" in str(error) or "over this connection's limit" in str(error)
                refused += 1
            except TimeoutError:
                pass
        assert refused == 12, "a payload before a hello is refused, and so is a connection over the cap"
        still_serving(server)
    finally:
        for client in clients:
            client.close()


def test_a_truncated_frame_then_end_of_stream_gets_the_error_reply(server):
    with authenticated(server) as client:
        frame = Message("reset").encode()
        client.sendall(frame[:-3])
        client.shutdown(socket.SHUT_WR)
        with pytest.raises(ServerError, match="closed inside a message"):
            receive(client)
    still_serving(server)
