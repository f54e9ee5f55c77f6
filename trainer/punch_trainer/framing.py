"""The one framing of every byte stream the trainer speaks: the training server's socket (sim/protocol.py, the
wire format of docs/protocol.md and punch_core's protocol) and a reward worker's pipes (reward/sandbox.py).

A frame is two little-endian u32 lengths, the header's and the payload's, then the header (JSON text) and the
payload (raw bytes). `write_frame` and `read_frame` are the pair; they take the stream as a function that writes
all of some bytes, or reads exactly a count of them, so each transport keeps its own deadline and its own errors
for a stream that ends or stalls. A frame whose lengths break the reader's `FrameLimits` raises
`FrameTooLargeError` before anything more is read; what the header says is the caller's to check
(`ProtocolError`, sim/protocol.py, for the server's messages)."""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

from punch_trainer.errors import PunchError

PREFIX = struct.Struct("<II")
"""the header's and the payload's lengths"""
MAX_LENGTH = 2**32 - 1
"""a u32's largest value: no header or payload can be longer"""


class FrameError(PunchError):
    """A frame broke the framing: a length out of bounds, or a header or payload of no sense to its reader."""


class FrameTooLargeError(FrameError):
    """A frame's header or payload is longer than its reader takes (or than a u32 can say)."""


@dataclass(frozen=True)
class FrameLimits:
    """The longest header and payload a reader takes (bytes); a header is never empty."""

    max_header_bytes: int
    max_payload_bytes: int = MAX_LENGTH


def write_frame(write: Callable[[bytes | memoryview], object], header: bytes, payload: bytes | memoryview = b"") -> None:
    """Writes one frame: `write(prefix + header)`, then `write(payload)` unless it is empty (so a large payload is
    not copied). FrameTooLargeError when a length does not fit a u32, or the header is empty."""
    body = memoryview(payload).cast("B")
    if not 0 < len(header) <= MAX_LENGTH or len(body) > MAX_LENGTH:
        raise FrameTooLargeError(f"a frame of a {len(header)}-byte header and a {len(body)}-byte payload cannot be framed")
    write(PREFIX.pack(len(header), len(body)) + header)
    if len(body):
        write(body)


def encode_frame(header: bytes, payload: bytes | memoryview = b"") -> bytes:
    """One frame as bytes (what `write_frame` writes)."""
    parts: list[bytes] = []
    write_frame(lambda data: parts.append(bytes(data)), header, payload)
    return b"".join(parts)


def read_frame(read_exactly: Callable[[int], bytes], limits: FrameLimits) -> tuple[bytes, bytes]:
    """Reads one frame with `read_exactly(count)` (which returns exactly `count` bytes or raises the transport's
    own error); returns its header and payload. FrameTooLargeError, before reading on, when its header is empty
    or a length is over `limits`."""
    header_length, payload_length = PREFIX.unpack(read_exactly(PREFIX.size))
    if not 0 < header_length <= limits.max_header_bytes or payload_length > limits.max_payload_bytes:
        raise FrameTooLargeError(f"bad frame lengths {header_length}, {payload_length} (a header of 1 to "
                                 f"{limits.max_header_bytes} bytes, a payload of at most {limits.max_payload_bytes})")
    return read_exactly(header_length), read_exactly(payload_length)
