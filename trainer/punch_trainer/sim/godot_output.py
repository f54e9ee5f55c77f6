"""The output of a long-lived Godot process (a training server), read for the whole life of the process.

A pipe holds only about 64 kB: if the trainer stopped reading it, a server that logs (refused intruders,
closed clients) would block in write() and answer no one. So a daemon thread reads every line until the
process ends, keeps only the last ones (for error messages) and signals the line the trainer waits for."""

from __future__ import annotations

import collections
import threading
from typing import IO

KEPT_LINES = 200
"""lines kept for error messages; older ones are dropped"""
LINE_CHARS = 2000
"""a longer line is kept in pieces of this size"""


class GodotOutput:
    """Reads `stream` on a thread of its own until it ends; `wait_for` returns the first line that starts with
    `watch`, and `tail` the last lines read."""

    def __init__(self, stream: IO[str], watch: str):
        self._stream = stream
        self._watch = watch
        self._lines: collections.deque[str] = collections.deque(maxlen=KEPT_LINES)
        self._lock = threading.Lock()
        self._seen = threading.Event()
        """set when the watched line came, or the stream ended"""
        self._watched: str | None = None
        self.lines_read = 0
        self._thread = threading.Thread(target=self._read, name="godot-output", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            while line := self._stream.readline(LINE_CHARS):
                with self._lock:
                    self._lines.append(line if line.endswith("\n") else line + "\n")
                    self.lines_read += 1
                if self._watched is None and line.startswith(self._watch):
                    self._watched = line
                    self._seen.set()
        except (OSError, ValueError):  # the stream was closed under us: the process is being stopped
            pass
        finally:
            self._seen.set()

    def wait_for(self, timeout_s: float) -> str | None:
        """The watched line once it came; None if the stream ended first (`ended`) or `timeout_s` passed."""
        self._seen.wait(timeout_s)
        return self._watched

    @property
    def ended(self) -> bool:
        """Whether the stream has ended (the process exited, or closed its output)."""
        return not self._thread.is_alive()

    def join(self, timeout_s: float) -> bool:
        """Waits up to `timeout_s` for the stream to end; returns whether it did."""
        self._thread.join(timeout_s)
        return not self._thread.is_alive()

    def text(self) -> str:
        """The lines kept (the last `KEPT_LINES`)."""
        with self._lock:
            return "".join(self._lines)

    def tail(self, lines: int = 30) -> str:
        with self._lock:
            return "".join(list(self._lines)[-lines:])
