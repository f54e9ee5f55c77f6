"""Hostile input to the real training server: each bad message gets a clear error reply and the server
goes on serving (a broken frame closes that connection only; a new one is served)."""

import socket
import struct

import numpy as np
import pytest

from punch_trainer.sim.protocol import Message, ProtocolError, ServerError, hello_message, receive
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
        server.request(Message("hello", fields, arrays))
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
        client.sendall(hello_message().encode())
        assert receive(client).type == "hello"
    still_serving(server)


def test_handshake_describes_the_spec(server):
    info = server.info
    assert info.slot_count == 2 and info.decision_period == 5 and info.physics_hz == 120
    assert len(info.action_names) == 10 and len(info.observation_names) == 45
    assert len(info.spec_hash) == 16 and info.spec_version >= 1
    assert "exploit_flags" in info.feature_names


def test_python_codec_round_trip_and_garbage():
    message = Message("step", {"n": 2}, {"actions": np.arange(20, dtype=np.float32).reshape(2, 10)})
    encoded = message.encode()
    header_length, payload_length = struct.unpack("<II", encoded[:8])
    decoded = Message.decode(encoded[8:8 + header_length], encoded[8 + header_length:])
    assert decoded.type == "step" and decoded.fields == {"n": 2}
    np.testing.assert_array_equal(decoded.arrays["actions"], message.arrays["actions"])
    with pytest.raises(ProtocolError):
        Message.decode(b"[1, 2]", b"")
    with pytest.raises(ProtocolError):
        Message.decode(b'{"type": "x", "arrays": [{"name": "a", "shape": [4]}]}', b"\x00" * 8)
