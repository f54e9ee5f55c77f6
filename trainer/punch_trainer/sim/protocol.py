"""Client side of the training-server wire format (docs/protocol.md): a JSON header and little-endian f32
arrays, framed by two u32 lengths (framing.py, the trainer's one framing). The Rust side is punch_core's
protocol."""

from __future__ import annotations

import json
import socket
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from punch_trainer.errors import PunchError
from punch_trainer.framing import FrameError, FrameLimits, encode_frame, read_frame
from punch_trainer.sim.conditions import EpisodeConditions

PROTOCOL_VERSION = 8
MAX_HEADER_BYTES = 64 * 1024
MAX_PAYLOAD_BYTES = 256 * 1024 * 1024
LIMITS = FrameLimits(MAX_HEADER_BYTES, MAX_PAYLOAD_BYTES)
"""the longest frame the trainer reads from a server"""


class ProtocolError(FrameError):
    """A frame's header or arrays broke the wire format (its lengths break it with `FrameTooLargeError`)."""


class ServerError(PunchError):
    """The server answered a request with an error message."""


class ServerTimeoutError(PunchError):
    """The server did not answer in time."""


class ServerClosedError(PunchError):
    """The server closed the connection."""


@dataclass
class Message:
    """A message: its header fields and its named float32 arrays."""

    type: str
    fields: dict[str, Any] = field(default_factory=dict)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    def parts(self) -> tuple[bytes, bytes]:
        """The frame's header (JSON) and payload (the arrays, little-endian f32, in order)."""
        arrays = {name: np.ascontiguousarray(value, dtype="<f4") for name, value in self.arrays.items()}
        header = {"type": self.type, **self.fields,
                  "arrays": [{"name": name, "shape": list(value.shape)} for name, value in arrays.items()]}
        return json.dumps(header, separators=(",", ":")).encode(), b"".join(value.tobytes() for value in arrays.values())

    def encode(self) -> bytes:
        """The whole frame."""
        return encode_frame(*self.parts())

    @classmethod
    def decode(cls, header_bytes: bytes, payload: bytes) -> Message:
        try:
            header = json.loads(header_bytes)
        except (UnicodeDecodeError, json.JSONDecodeError) as error:
            raise ProtocolError(f"header is not JSON: {error}") from None
        if not isinstance(header, dict) or not isinstance(header.get("type"), str):
            raise ProtocolError("header is not an object with a string 'type'")
        descriptors = header.pop("arrays", [])
        if not isinstance(descriptors, list):
            raise ProtocolError("'arrays' must be a list")
        arrays, offset = {}, 0
        for descriptor in descriptors:
            shape = descriptor.get("shape") if isinstance(descriptor, dict) else None
            if (not isinstance(descriptor.get("name") if isinstance(descriptor, dict) else None, str) or not isinstance(shape, list)
                    or not all(isinstance(d, int) and not isinstance(d, bool) and d >= 0 for d in shape)):
                raise ProtocolError(f"bad array descriptor {str(descriptor)[:80]}: needs a name and a shape of non-negative integers")
            count = 1
            for d in shape:  # Python ints: a huge declared shape cannot overflow, it is just too long
                count *= d
            if 4 * count > len(payload) - offset:
                raise ProtocolError(f"payload too short for array '{descriptor['name']}' of shape {shape}")
            arrays[descriptor["name"]] = np.frombuffer(payload[offset:offset + 4 * count], dtype="<f4").reshape(shape)
            offset += 4 * count
        if offset != len(payload):
            raise ProtocolError(f"payload has {len(payload)} bytes, arrays describe {offset}")
        message_type = header.pop("type")
        return cls(message_type, header, arrays)


# The requests, built in one place each (fields and arrays: docs/protocol.md, Messages).
Placement = EpisodeConditions | Mapping[str, float]
"""a placement, or a JSON object of some of its values (the server takes the rest from its default)"""
Bags = Sequence[Placement] | Placement | None


def _wire_bags(bags: Sequence[Placement] | Placement) -> object:
    def wire(bag: Placement) -> dict[str, float]:
        return bag.to_wire() if isinstance(bag, EpisodeConditions) else dict(bag)

    return wire(bags) if isinstance(bags, EpisodeConditions | Mapping) else [wire(bag) for bag in bags]


def hello_message(secret: str) -> Message:
    """The handshake; `secret` is the one the server was started with (`TrainingServer.secret`)."""
    return Message("hello", {"protocol_version": PROTOCOL_VERSION, "secret": secret})


def reset_message(frames: int, *, bags: Bags = None, smoothing_window: int = 1, lead_in: np.ndarray | None = None) -> Message:
    """`lead_in`: raw actions [N, decisions, A] played (unsmoothed, unrecorded) before the episode starts, so
    that it starts from wherever they leave each character: the end of an earlier punch, mid-recovery."""
    fields: dict[str, object] = {"frames": frames, "smoothing_window": smoothing_window}
    if bags is not None:
        fields["bags"] = _wire_bags(bags)
    arrays = {"lead_in": np.asarray(lead_in, dtype=np.float32)} if lead_in is not None else {}
    return Message("reset", fields, arrays)


def step_message(actions: np.ndarray) -> Message:
    """Actions [N, A] for every slot."""
    return Message("step", arrays={"actions": np.asarray(actions, dtype=np.float32)})


def rollout_message(actions: np.ndarray, *, bags: Bags = None, smoothing_window: int = 1,
                    lead_in: np.ndarray | None = None) -> Message:
    """Open-loop raw actions [N, decisions, A] for every slot, from a fresh reset (after `lead_in` [N, decisions, A],
    unrecorded, when given: a start from a stance's guard)."""
    fields: dict[str, object] = {"smoothing_window": smoothing_window}
    if bags is not None:
        fields["bags"] = _wire_bags(bags)
    arrays = {"actions": np.asarray(actions, dtype=np.float32)}
    if lead_in is not None:
        arrays["lead_in"] = np.asarray(lead_in, dtype=np.float32)
    return Message("rollout", fields, arrays)


def close_message() -> Message:
    return Message("close")


def _receive_exactly(sock: socket.socket, count: int) -> bytes:
    chunks, remaining = [], count
    while remaining:
        try:
            chunk = sock.recv(min(remaining, 1 << 20))
        except TimeoutError:
            raise ServerTimeoutError("the server did not answer in time") from None
        if not chunk:
            raise ServerClosedError("the server closed the connection")
        chunks.append(chunk)
        remaining -= len(chunk)
    return b"".join(chunks)


def receive(sock: socket.socket) -> Message:
    """Reads one message; an `error` reply raises ServerError, a frame over `LIMITS` FrameTooLargeError, a
    malformed message ProtocolError (both FrameErrors)."""
    message = Message.decode(*read_frame(lambda count: _receive_exactly(sock, count), LIMITS))
    if message.type == "error":
        raise ServerError(message.fields.get("message", "unknown server error"))
    return message
