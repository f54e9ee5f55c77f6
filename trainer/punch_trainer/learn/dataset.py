"""Trajectory datasets: the trajectory search's best trajectory recorded decision by decision (what
pretraining learns from), and loading several of them as one.

A dataset (`dataset.npz`) holds per decision the observation seen, the raw and executed action and the
reward, every frame's features, the bag's placement, and the policy contract of the episodes it was recorded in
(`policy_metadata`, as the training server announced it, with the reach volume the training covers), which
every policy trained on it carries."""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from punch_trainer.errors import PunchError
from punch_trainer.learn.reach import ReachVolume
from punch_trainer.learn.search import SearchArgs, SearchResult
from punch_trainer.policy_file import REACH_VOLUME
from punch_trainer.reward.rewards import Reward, decision_rewards, score
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.conditions import EpisodeConditions
from punch_trainer.sim.server import ServerInfo
from punch_trainer.sim.server_group import ServerGroup, SimulatorRestarts


class DatasetError(PunchError):
    """A dataset file is missing, unreadable, from another spec, or lacks the policy contract."""


def record_dataset(result: SearchResult, reward: Reward, args: SearchArgs, *, backend: Backend = LOCAL) -> dict[str, np.ndarray]:
    """The dataset of a search at the default placement (`record_datasets`), for a single-spot policy."""
    return record_datasets([result], reward, args, backend=backend)[0]


def record_datasets(results: list[SearchResult], reward: Reward, args: SearchArgs, bags: list[EpisodeConditions] | None = None,
                    reach: ReachVolume | None = None, *, backend: Backend = LOCAL,
                    lead_in: np.ndarray | None = None) -> list[dict[str, np.ndarray]]:
    """Steps through best trajectories one decision at a time, each in the slot it was found in, of a server
    of the same size as the search's (so that each is bitwise the same trajectory: docs/env.md, Episodes),
    with its bag placement (`bags`, default: the spec's), on `backend`, and stores what each decision saw and did. The
    recording must reproduce the search's features exactly. `reach` (default: the one placement) goes into
    each dataset's policy contract, so every policy trained on them states what it covers. `lead_in` [L, A]: what
    every rollout of the search played first (`placement_search`'s, one start for all), played again before each
    recording."""
    slot_count = args.characters_per_process
    placed: list[EpisodeConditions | None] = list(bags) if bags else [None] * len(results)
    recorded: list[dict[str, np.ndarray] | None] = [None] * len(results)
    pending = list(range(len(results)))
    group = ServerGroup(1, slot_count, args.decision_period, backend=backend)
    restarts = SimulatorRestarts(group.restart)  # each pass is played again in a fresh process if one fails
    try:
        info = group.info
        reach = reach or ReachVolume.spot(placed[0] or info.default_bag)
        while pending:
            # One pass plays every pending trajectory whose slot is still free in it.
            by_slot: dict[int, int] = {}
            for index in pending:
                by_slot.setdefault(results[index].best_slot, index)
            pending = [index for index in pending if index not in by_slot.values()]
            slot_bags = [info.default_bag] * slot_count
            for slot, index in by_slot.items():
                slot_bags[slot] = placed[index] or info.default_bag
            passed = restarts.run(functools.partial(_play_pass, group, results, by_slot, slot_bags, reward, args, lead_in))
            contract = dict(passed.policy_metadata, **{REACH_VOLUME: reach.to_json()})
            for slot, index in by_slot.items():
                recorded[index] = _dataset(results[index], reward, args, info, contract, slot_bags[slot],
                                           passed.observations[slot], passed.executed[slot], passed.frames[slot])
    finally:
        group.close()
    return [dataset for dataset in recorded if dataset is not None]


@dataclass
class _Pass:
    """What one pass of `record_datasets` saw, per slot."""

    policy_metadata: dict[str, str]
    observations: list[list[np.ndarray]]
    executed: list[list[np.ndarray]]
    frames: list[list[np.ndarray]]


def _play_pass(group: ServerGroup, results: list[SearchResult], by_slot: dict[int, int], slot_bags: list[EpisodeConditions],
               reward: Reward, args: SearchArgs, lead_in: np.ndarray | None = None) -> _Pass:
    """Plays the trajectories `by_slot` (slot -> result) decision by decision on the group's server, every slot after
    `lead_in` [L, A] when given."""
    group.replace_idle()
    server, info, slot_count = group.servers[0], group.info, len(slot_bags)
    starts = None if lead_in is None else np.tile(np.asarray(lead_in, dtype=np.float32), (slot_count, 1, 1))
    reply = server.reset(reward.frames, bags=slot_bags, smoothing_window=args.smoothing_window, lead_in=starts)
    played = _Pass(reply.fields["policy_metadata"], [[reply.arrays["observations"][slot]] for slot in range(slot_count)],
                   [[] for _ in range(slot_count)], [[] for _ in range(slot_count)])
    for decision in range(len(results[0].best_actions)):
        actions = np.zeros((slot_count, info.action_size), dtype=np.float32)
        for slot, index in by_slot.items():
            actions[slot] = results[index].best_actions[decision]
        step = server.step(actions)
        for slot in by_slot:
            played.observations[slot].append(step.arrays["observations"][slot])
            played.executed[slot].append(step.arrays["executed_actions"][slot, 0])
            played.frames[slot].append(step.arrays["features"][slot])
    return played


def _dataset(result: SearchResult, reward: Reward, args: SearchArgs, info: ServerInfo, contract: dict[str, str],
             bag: EpisodeConditions, observations: list[np.ndarray], executed: list[np.ndarray],
             frames: list[np.ndarray]) -> dict[str, np.ndarray]:
    features = np.concatenate(frames)
    decisions = len(result.best_actions)
    rewards = decision_rewards(reward, features[:decisions * args.decision_period], info.feature_names, args.decision_period)
    if not np.array_equal(features, result.best_features):
        raise RuntimeError("recording the best trajectory step by step did not reproduce its features; the physics is not deterministic")
    return {
        "observations": np.stack(observations[:-1]).astype(np.float32),
        "next_observations": np.stack(observations[1:]).astype(np.float32),
        "actions": result.best_actions.astype(np.float32),
        "executed_actions": np.stack(executed).astype(np.float32),
        "rewards": rewards.astype(np.float32),
        "features": features.astype(np.float32),
        "feature_names": np.array(info.feature_names),
        "observation_names": np.array(info.observation_names),
        "spec_hash": np.array(info.spec_hash),
        "policy_metadata": np.array(json.dumps(contract, sort_keys=True)),
        "bag": np.array(json.dumps(bag.to_wire(), sort_keys=True)),
        "reward": np.array(reward.name),
        "frames": np.array(reward.frames),
        "decision_period": np.array(args.decision_period),
        "smoothing_window": np.array(args.smoothing_window),
        "physics_hz": np.array(info.physics_hz),
        "return": np.array(float(score(reward, features, info.feature_names))),
    }


def load_datasets(paths: list[Path]) -> dict[str, Any]:
    """Concatenates the decision-level arrays of several datasets. They must share one policy contract (spec,
    episode length, smoothing window), which the result carries in `policy_metadata` (a dict), with the
    datasets' distinct reward names in `reward_names`."""
    parts = []
    for path in paths:
        try:
            parts.append(dict(np.load(path)))
        except (OSError, ValueError) as error:
            raise DatasetError(f"cannot read dataset {path}: {error}") from None
    contracts = []
    for path, part in zip(paths, parts, strict=True):
        if "policy_metadata" not in part:
            raise DatasetError(f"{path} holds no policy contract (it was written by an older punch search); run the search again")
        contracts.append(json.loads(str(part["policy_metadata"])))
    if any(contract != contracts[0] for contract in contracts):
        raise DatasetError("the datasets come from different policy contracts (spec, episode length or smoothing window): "
                           + "; ".join(f"{path}: {contract}" for path, contract in zip(paths, contracts, strict=True)))
    out: dict[str, Any] = {key: np.concatenate([p[key] for p in parts]) for key in ("observations", "actions", "rewards")}
    out["returns_to_go"] = np.concatenate([returns_to_go(p["rewards"], 1.0) for p in parts])
    out["spec_hash"] = parts[0]["spec_hash"]
    out["policy_metadata"] = contracts[0]
    out["reward_names"] = sorted({str(p["reward"]) for p in parts})
    return out


def returns_to_go(rewards: np.ndarray, gamma: float) -> np.ndarray:
    """Sum of the (discounted) rewards from each decision to the end of the episode."""
    out = np.zeros_like(rewards, dtype=np.float64)
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        running = rewards[t] + gamma * running
        out[t] = running
    return out.astype(np.float32)
