"""K training servers started, restarted and closed together, and the restart rule: a Godot process that
crashes, is killed or stops answering (its reply timeout) is replaced by a fresh one, the handshake is made
again, and the work is run again from its start. Starting the servers is under the same rule (a start that
fails as a running server can, or finds the server busy, is tried again), and servers left idle for most of
their idle timeout (they quit at its end) are replaced before the next episode, whatever the trainer did
meanwhile (`ServerGroup.replace_idle`)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TypeVar

from punch_trainer.errors import PunchError
from punch_trainer.framing import FrameError
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.protocol import ServerClosedError, ServerTimeoutError
from punch_trainer.sim.server import ServerBusyError, ServerConnection, ServerInfo

# Failures that a fresh Godot process fixes (a server's error reply is not one of them: it would repeat). A
# busy server is one whose connections other processes held: a fresh one is on another port.
SIMULATOR_FAILURES = (ServerClosedError, ServerTimeoutError, FrameError, ConnectionError, ServerBusyError)

T = TypeVar("T")


class SimulatorCrashError(PunchError):
    """The simulator kept failing after the allowed number of restarts."""


class SimulatorRestarts:
    """Runs work against Godot processes; when one crashes, is killed or hangs, calls `restart` (fresh
    processes, handshake made again) and runs the work again from its start, at most `limit` times in all."""

    def __init__(self, restart: Callable[[], None], limit: int = 3):
        self.restart = restart
        self.limit = limit
        self.count = 0

    def run(self, attempt: Callable[[], T]) -> T:
        restarting = False
        while True:
            try:
                if restarting:  # inside the try: a restart can fail the same way (a Ray node going away meanwhile)
                    self.restart()
                    restarting = False
                return attempt()
            except SIMULATOR_FAILURES as error:
                if self.count >= self.limit:
                    raise SimulatorCrashError(f"the simulator failed again after {self.count} restarts: {error}") from error
                self.count += 1
                print(f"punch: a Godot process failed ({type(error).__name__}: {error}); restarting it "
                      f"({self.count}/{self.limit}) and running the work again", file=sys.stderr)
                restarting = True


class ServerGroup:
    """K training servers with N characters each, started, restarted and closed together on `backend`: what
    the rollout pool and the vector env hold."""

    def __init__(self, processes: int, characters_per_process: int, decision_period: int = 5, *, backend: Backend = LOCAL,
                 max_restarts: int = 3):
        self._start: Callable[[], list[ServerConnection]] = lambda: backend.start_servers(processes, characters_per_process, decision_period)
        # A failed start has closed what it started (Backend.start_servers): trying again is starting again.
        self.servers = SimulatorRestarts(lambda: None, max_restarts).run(self._start)
        self.info: ServerInfo = self.servers[0].info  # the handshake: rates, names, spec hash
        self.idle_replacements = 0
        """how many times idle servers were replaced (`replace_idle`; not restarts: nothing failed)"""

    def replace_idle(self) -> bool:
        """Replaces the servers if one has had no request for most of its idle timeout (it quits at its end),
        as the work is about to start again from a fresh episode (a long pretraining, a report, a checkpoint
        in between); returns whether it did. A rollout or episode starts from the same reset in any process,
        so the results are bitwise those of the old servers."""
        if not any(server.idle_expired() for server in self.servers):
            return False
        self.restart()
        self.idle_replacements += 1
        return True

    def restart(self) -> None:
        """Replaces every process with a fresh one (after one failed); the handshake is made again."""
        self.close()
        self.servers = self._start()  # under the caller's restart rule, which counts a failure here too
        if self.servers[0].info.spec_hash != self.info.spec_hash:
            raise SimulatorCrashError("the restarted simulator has another observation spec")

    def close(self) -> None:
        for server in self.servers:
            server.close()
