"""Property tests of the wire format: the Python decoder on random bytes, and the live training server fed
random and mutated frames on one connection while another client keeps being served. Bounded in time:
a fixed number of examples, no deadline."""

import contextlib
import json
import socket
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from punch_trainer.sim.protocol import Message, ProtocolError, ServerClosedError, ServerError, hello_message, receive
from punch_trainer.sim.server import TrainingServer

json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
                           lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4),
                           max_leaves=12)


@settings(max_examples=400, deadline=None)
@given(header=st.binary(max_size=200), payload=st.binary(max_size=64))
def test_decoding_random_bytes_is_a_message_or_a_protocol_error(header, payload):
    with contextlib.suppress(ProtocolError):
        Message.decode(header, payload)


@settings(max_examples=400, deadline=None)
@given(header=st.dictionaries(st.sampled_from(["type", "arrays", "n"]), json_values, max_size=3), floats=st.integers(0, 8))
def test_decoding_random_json_headers_is_a_message_or_a_protocol_error(header, floats):
    with contextlib.suppress(ProtocolError):
        Message.decode(json.dumps(header).encode(), b"\x00" * (4 * floats))


@settings(max_examples=200, deadline=None)
@given(kind=st.text(min_size=1, max_size=10), arrays=st.dictionaries(
    st.text(min_size=1, max_size=6), st.lists(st.floats(width=32), max_size=12).map(lambda v: np.array(v, dtype=np.float32)), max_size=3))
def test_messages_round_trip_bit_for_bit(kind, arrays):
    encoded = Message(kind, {"x": 1}, arrays).encode()
    header_length, _ = struct.unpack("<II", encoded[:8])
    decoded = Message.decode(encoded[8:8 + header_length], encoded[8 + header_length:])
    assert decoded.type == kind and decoded.fields == {"x": 1}
    for name, values in arrays.items():
        assert decoded.arrays[name].tobytes() == values.tobytes()


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


@pytest.fixture(scope="module")
def server():
    with TrainingServer(2) as server:
        yield server


def valid_frames():
    """Frames to mutate. None of them changes the shared episode (a reset or a well-formed step from the
    intruder would race the trainer's own requests), so the trainer's checks stay exact."""
    hello = hello_message("not-this-server-s-secret").encode()
    bad_step = Message("step", arrays={"actions": np.zeros((2, 9), dtype=np.float32)}).encode()
    unknown = Message("jump", {"frames": 10}).encode()
    return st.sampled_from([hello, bad_step, unknown])


@st.composite
def hostile_frames(draw):
    """Random bytes, or a valid frame mutated: truncated, bytes flipped, lengths rewritten, NaN inserted."""
    kind = draw(st.sampled_from(["random", "truncate", "flip", "lengths", "nan"]))
    if kind == "random":
        return draw(st.binary(min_size=1, max_size=300))
    frame = bytearray(draw(valid_frames()))
    if kind == "truncate":
        return bytes(frame[:draw(st.integers(1, len(frame) - 1))])
    if kind == "flip":
        for _ in range(draw(st.integers(1, 6))):
            frame[draw(st.integers(0, len(frame) - 1))] = draw(st.integers(0, 255))
        return bytes(frame)
    if kind == "lengths":
        return struct.pack("<II", draw(st.integers(0, 2**32 - 1)), draw(st.integers(0, 2**32 - 1))) + bytes(frame[8:])
    nan = Message("step", arrays={"actions": np.full((2, 10), draw(st.sampled_from([np.nan, np.inf, -np.inf])), dtype=np.float32)})
    return nan.encode()


@pytest.mark.godot
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(frames=st.lists(hostile_frames(), min_size=1, max_size=3))
def test_the_server_answers_hostile_frames_and_keeps_serving(server, frames):
    with socket.create_connection(("127.0.0.1", server.port), timeout=10) as intruder:
        intruder.sendall(b"".join(frames))
        # The intruder may have left half a frame: the trainer's own connection is served all the same.
        assert server.reset().type == "reset_done"
        assert server.step(np.zeros((2, 10))).type == "step_done"
        intruder.shutdown(socket.SHUT_WR)
        for _ in range(len(frames) + 1):  # every complete frame is answered, then the server hangs up
            try:
                receive(intruder)
            except (ServerError, ProtocolError):
                continue
            except (ServerClosedError, ConnectionError):
                break
            except TimeoutError:
                pytest.fail(f"the server neither answered nor closed after {frames!r:.200}")
