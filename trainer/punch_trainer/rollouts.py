"""Batches of open-loop rollouts spread over K Godot processes x N characters each.

A Godot process that crashes, is killed or stops answering (its reply timeout) is restarted, the handshake
is made again, and the batch is run again. A rollout always starts from the same reset and the same slot
gives bitwise the same features in any process, so a restarted run ends exactly where an uninterrupted one
would."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from punch_trainer.errors import PunchError
from punch_trainer.protocol import Message, ProtocolError, ServerClosedError, ServerTimeoutError
from punch_trainer.server import TrainingServer, exchange, start_servers

# Failures that a fresh Godot process fixes (a server's error reply is not one of them: it would repeat).
SIMULATOR_FAILURES = (ServerClosedError, ServerTimeoutError, ProtocolError, ConnectionError)

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
        while True:
            try:
                return attempt()
            except SIMULATOR_FAILURES as error:
                if self.count >= self.limit:
                    raise SimulatorCrashError(f"the simulator failed again after {self.count} restarts: {error}") from error
                self.count += 1
                print(f"punch: a Godot process failed ({type(error).__name__}: {error}); restarting it "
                      f"({self.count}/{self.limit}) and running the work again", file=sys.stderr)
                self.restart()


class ServerGroup:
    """K training servers with N characters each, started, restarted and closed together: what the rollout
    pool and the vector env hold."""

    def __init__(self, processes: int, characters_per_process: int, decision_period: int = 5):
        self._start = lambda: start_servers(processes, characters_per_process, decision_period)
        self.servers = self._start()
        self.info = self.servers[0].info  # the handshake: rates, names, spec hash

    def restart(self) -> None:
        """Replaces every process with a fresh one (after one failed); the handshake is made again."""
        self.close()
        self.servers = self._start()
        if self.servers[0].info.spec_hash != self.info.spec_hash:
            raise SimulatorCrashError("the restarted simulator has another observation spec")

    def close(self) -> None:
        for server in self.servers:
            server.close()


class RolloutPool:
    """Runs any number of open-loop action sequences, `slots` at a time in parallel processes."""

    def __init__(self, processes: int = 1, characters_per_process: int = 32, *, decision_period: int = 5,
                 max_restarts: int = 3):
        self.group = ServerGroup(processes, characters_per_process, decision_period)
        self.info = self.group.info
        self.characters_per_process = characters_per_process
        self.slots = processes * characters_per_process
        self._restarts = SimulatorRestarts(self.group.restart, max_restarts)

    @property
    def servers(self) -> list[TrainingServer]:
        return self.group.servers

    @property
    def restarts(self) -> int:
        """How many times the Godot processes were restarted."""
        return self._restarts.count

    def run(self, actions: np.ndarray, smoothing_window: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Raw actions [M, decisions, 10] -> (features [M, frames, F], executed actions [M, decisions, 10])."""
        actions = np.asarray(actions, dtype=np.float32)
        count = actions.shape[0]
        features, executed = [], []
        for start in range(0, count, self.slots):
            chunk = actions[start:start + self.slots]
            padded = np.zeros((self.slots, *actions.shape[1:]), dtype=np.float32)
            padded[:len(chunk)] = chunk  # unused slots run the guard pose; their results are dropped
            parts = np.split(padded, len(self.servers))
            messages = [Message("rollout", {"smoothing_window": smoothing_window}, {"actions": part}) for part in parts]
            replies = self._restarts.run(lambda: exchange(self.servers, messages))
            features.append(np.concatenate([r.arrays["features"] for r in replies])[:len(chunk)])
            executed.append(np.concatenate([r.arrays["executed_actions"] for r in replies])[:len(chunk)])
        return np.concatenate(features), np.concatenate(executed)

    def close(self) -> None:
        self.group.close()

    def __enter__(self) -> RolloutPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
