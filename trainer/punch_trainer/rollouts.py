"""Batches of open-loop rollouts spread over K Godot processes x N characters each."""

from __future__ import annotations

import numpy as np

from punch_trainer.protocol import Message
from punch_trainer.server import exchange, start_servers


class RolloutPool:
    """Runs any number of open-loop action sequences, `slots` at a time in parallel processes."""

    def __init__(self, processes: int = 1, characters_per_process: int = 32, *, decision_period: int = 5):
        self.servers = start_servers(processes, characters_per_process, decision_period)
        self.info = self.servers[0].info
        self.characters_per_process = characters_per_process
        self.slots = processes * characters_per_process

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
            replies = exchange(self.servers, [Message("rollout", {"smoothing_window": smoothing_window}, {"actions": part}) for part in parts])
            features.append(np.concatenate([r.arrays["features"] for r in replies])[:len(chunk)])
            executed.append(np.concatenate([r.arrays["executed_actions"] for r in replies])[:len(chunk)])
        return np.concatenate(features), np.concatenate(executed)

    def close(self) -> None:
        for server in self.servers:
            server.close()

    def __enter__(self) -> RolloutPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
