"""Batches of open-loop rollouts spread over K Godot processes x N characters each.

A Godot process that crashes, is killed or stops answering (its reply timeout) is restarted, the handshake
is made again, and the batch is run again; a process left idle for most of its idle timeout is replaced
before the next batch. A rollout always starts from the same reset and the same slot
gives bitwise the same features in any process, so a restarted run ends exactly where an uninterrupted one
would."""

from __future__ import annotations

import functools

import numpy as np

from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.conditions import EpisodeConditions
from punch_trainer.sim.protocol import Message, rollout_message
from punch_trainer.sim.server import ServerConnection, exchange
from punch_trainer.sim.server_group import ServerGroup, SimulatorRestarts


class RolloutPool:
    """Runs any number of open-loop action sequences, `slots` at a time in parallel processes (started on
    `backend`: local processes or Ray workers)."""

    def __init__(self, processes: int = 1, characters_per_process: int = 32, *, decision_period: int = 5,
                 max_restarts: int = 3, backend: Backend = LOCAL):
        self.group = ServerGroup(processes, characters_per_process, decision_period, backend=backend)
        self.info = self.group.info
        self.characters_per_process = characters_per_process
        self.slots = processes * characters_per_process
        self._restarts = SimulatorRestarts(self.group.restart, max_restarts)

    @property
    def servers(self) -> list[ServerConnection]:
        return self.group.servers

    @property
    def restarts(self) -> int:
        """How many times the Godot processes were restarted."""
        return self._restarts.count

    def run(self, actions: np.ndarray, smoothing_window: int = 1,
            bags: list[EpisodeConditions] | None = None, lead_in: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Raw actions [M, decisions, 10] -> (features [M, frames, F], executed actions [M, decisions, 10]).
        `bags`: one placement per sequence (default: the spec's); `lead_in`: [M, decisions, 10] each sequence plays
        first, unrecorded (a start from a stance's guard; default: the square guard at rest)."""
        actions = np.asarray(actions, dtype=np.float32)
        count = actions.shape[0]
        if bags is not None and len(bags) != count:
            raise ValueError(f"{len(bags)} bag placements for {count} action sequences")
        if lead_in is not None and (lead_in.ndim != 3 or lead_in.shape[0] != count or lead_in.shape[2] != actions.shape[2]):
            raise ValueError(f"a lead-in of shape {lead_in.shape} for {count} action sequences of {actions.shape[2]} values")
        features, executed = [], []
        per_process = self.characters_per_process
        for start in range(0, count, self.slots):
            chunk = actions[start:start + self.slots]
            padded = np.zeros((self.slots, *actions.shape[1:]), dtype=np.float32)
            padded[:len(chunk)] = chunk  # unused slots run the guard pose; their results are dropped
            parts = np.split(padded, len(self.servers))
            lead_ins: list[np.ndarray | None] = [None] * len(parts)
            if lead_in is not None:
                padded_lead_in = np.zeros((self.slots, *lead_in.shape[1:]), dtype=np.float32)
                padded_lead_in[:len(chunk)] = lead_in[start:start + self.slots]
                lead_ins = list(np.split(padded_lead_in, len(self.servers)))
            if bags is None:
                messages = [rollout_message(part, smoothing_window=smoothing_window, lead_in=lead_ins[p]) for p, part in enumerate(parts)]
            else:
                chunk_bags = bags[start:start + self.slots]
                chunk_bags = chunk_bags + [self.info.default_bag] * (self.slots - len(chunk_bags))
                messages = [rollout_message(part, smoothing_window=smoothing_window, bags=chunk_bags[p * per_process:(p + 1) * per_process],
                                            lead_in=lead_ins[p])
                            for p, part in enumerate(parts)]
            replies = self._restarts.run(functools.partial(self._exchange, messages))
            features.append(np.concatenate([r.arrays["features"] for r in replies])[:len(chunk)])
            executed.append(np.concatenate([r.arrays["executed_actions"] for r in replies])[:len(chunk)])
        return np.concatenate(features), np.concatenate(executed)

    def _exchange(self, messages: list[Message]) -> list[Message]:
        # The servers of the moment: a restart replaces them, and so does a long idle time since the last batch.
        self.group.replace_idle()
        return exchange(self.servers, messages)

    def close(self) -> None:
        self.group.close()

    def __enter__(self) -> RolloutPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
