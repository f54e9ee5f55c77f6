"""The trainer's one framing (framing.py): the training server's socket and a reward worker's pipes frame with
`write_frame`/`read_frame`, which refuse a frame over the reader's limits before reading it, with a typed error."""

from __future__ import annotations

import ast
import os
import socket
import struct

import numpy as np
import pytest

from conftest import PROJECT_ROOT
from punch_trainer.framing import PREFIX, FrameError, FrameLimits, FrameTooLargeError, encode_frame, read_frame, write_frame
from punch_trainer.sim.protocol import LIMITS, Message, ProtocolError, ServerClosedError, receive

TRAINER = PROJECT_ROOT / "trainer" / "punch_trainer"


def reader(data: bytes):
    """`read_exactly` over bytes, counting what was read."""
    position = [0]

    def read_exactly(count: int) -> bytes:
        chunk = data[position[0]:position[0] + count]
        if len(chunk) < count:
            raise EOFError
        position[0] += count
        return chunk

    return read_exactly, position


def test_a_frame_round_trips_over_a_socket_and_a_pipe():
    payload = np.arange(12, dtype="<f8")
    a, b = socket.socketpair()
    with a, b, b.makefile("rb") as read:
        write_frame(a.sendall, b'{"x":1}', payload.data)
        assert read_frame(read.read, FrameLimits(64)) == (b'{"x":1}', payload.tobytes())
    read_fd, write_fd = os.pipe()
    with os.fdopen(write_fd, "wb") as w, os.fdopen(read_fd, "rb") as r:
        write_frame(w.write, b"{}")
        w.flush()
        assert read_frame(r.read, FrameLimits(64)) == (b"{}", b"")
    assert encode_frame(b"{}", b"ab") == struct.pack("<II", 2, 2) + b"{}ab"


@pytest.mark.parametrize("lengths", [(0, 0), (65, 0), (10, 1001), (2**32 - 1, 2**32 - 1)])
def test_lengths_over_the_limits_are_refused_before_reading_on(lengths):
    read_exactly, position = reader(struct.pack("<II", *lengths) + b"x" * 2000)
    with pytest.raises(FrameTooLargeError, match="bad frame lengths"):
        read_frame(read_exactly, FrameLimits(64, 1000))
    assert position[0] == PREFIX.size


def test_what_cannot_be_framed_is_not_written():
    written: list[bytes] = []
    with pytest.raises(FrameTooLargeError):
        write_frame(written.append, b"")
    assert written == []


def test_the_server_protocol_frames_with_it():
    message = Message("step", {"n": 1}, {"actions": np.ones((2, 10), dtype=np.float32)})
    a, b = socket.socketpair()
    with a, b:
        a.sendall(message.encode())
        assert receive(b).arrays["actions"].shape == (2, 10)
        a.sendall(struct.pack("<II", LIMITS.max_header_bytes + 1, 0))
        with pytest.raises(FrameTooLargeError):
            receive(b)
    a, b = socket.socketpair()
    with a, b:
        a.sendall(encode_frame(b"[1, 2]"))
        with pytest.raises(ProtocolError):
            receive(b)
        a.sendall(struct.pack("<II", 10, 0) + b"{")  # half a frame, then the server hangs up
        a.close()
        with pytest.raises(ServerClosedError):
            receive(b)
    assert issubclass(ProtocolError, FrameError) and issubclass(FrameTooLargeError, FrameError)


def test_no_module_of_the_trainer_frames_bytes_itself():
    """Lengths are packed and unpacked only in framing.py."""
    packing = sorted(f"{path.relative_to(TRAINER)}:{node.lineno}" for path in TRAINER.rglob("*.py") if path.name != "framing.py"
                     for node in ast.walk(ast.parse(path.read_text()))
                     if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "struct")
    assert packing == []
