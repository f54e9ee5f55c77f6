"""The punching world as Gymnasium environments, over real headless Godot/Jolt training servers.

Env card (full tables in docs/env.md)
-------------------------------------
- Action: 10 floats in [-1, 1], one per actuated DOF (waist 2, each shoulder 3, each elbow 1). 0 holds the
  guard pose; +1 / -1 set the joint target to the upper / lower limit. Held for `decision_period` physics
  frames (default 5 at 120 Hz). With `smoothing_window` n > 1 the executed action is the linearly weighted
  average of the last n actions (the paper's Eq. 1); `info["executed_action"]` shows it.
- Observation: 51 floats in the character's frame (+Z toward the bag, +X the character's left, +Y up):
  both fists' position and velocity, each fist's contact impulse on the bag, bag position and velocity,
  the 10 joint angles and speeds, the root's own velocity and turning (the character carried by its game, or
  in training by a `EpisodeConditions`'s body motion), and the episode phase (decision / decisions per episode).
- Features: every physics frame's 60 features (`feature_names`) come in `info["features"]`, shape
  [decision_period, 60]; rewards are computed from them in Python.
- Episode: `frames` physics frames (50 or 100: 10 or 20 decisions), always from the same initial state.
  At the last decision `terminated` is True, or `truncated` if the physics guard saw a joint come apart.
- Reward: a `Reward` (punch_trainer.reward.rewards: a preset, or a function of the features loaded with
  `load_reward`, with a motion style or none), scored on each decision's frames by `EpisodeScorer` (which a
  style's discount needs: it depends on the episode so far), so the step rewards add up to what `score` gives
  the whole episode; 0 when none is given.
- Registered with Gymnasium as `punch/Punch-v0` (`gym.make`, one character) and, for `gym.make_vec`, as a
  vector env (K processes x N characters) once `punch_trainer` is imported.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np

from punch_trainer.reward.rewards import EpisodeScorer, Reward
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.conditions import EpisodeConditions, EpisodeStart
from punch_trainer.sim.protocol import reset_message, step_message
from punch_trainer.sim.server import ServerConnection, ServerInfo, TrainingServer, exchange
from punch_trainer.sim.server_group import ServerGroup


def _spaces(info: ServerInfo) -> tuple[gym.spaces.Box, gym.spaces.Box]:
    """One character's observation and action spaces, from a server's handshake."""
    return (gym.spaces.Box(-np.inf, np.inf, (info.observation_size,), np.float32),
            gym.spaces.Box(-1.0, 1.0, (info.action_size,), np.float32))


Options = EpisodeStart | dict[str, Any] | None
"""a reset's options: an `EpisodeStart`, or Gymnasium's dict of the same (`bag`: one placement or one per
character, each a `EpisodeConditions` or a dict of some of its values over the default; `lead_in`)"""


def _episode_start(options: Options, default: EpisodeConditions, rng: np.random.Generator, count: int,
                   jitter_m: float) -> EpisodeStart:
    """The options as an `EpisodeStart` for `count` characters (the spec's default placement, from the
    handshake, where they name none), plus uniform jitter of +-jitter_m on each position coordinate drawn
    from the env's seeded generator."""
    if not isinstance(options, EpisodeStart):
        given = (options or {}).get("bag", default)
        listed = given if isinstance(given, list) else [given] * count
        bags = [bag if isinstance(bag, EpisodeConditions) else default.over(bag) for bag in listed]
        options = EpisodeStart(bags, (options or {}).get("lead_in"))
    if len(options.bags) != count:
        raise ValueError(f"the reset's options list {len(options.bags)} placements for {count} characters")
    if jitter_m > 0:
        jittered = []
        for bag in options.bags:
            distance_m, height_m, side_m = (float(value + rng.uniform(-jitter_m, jitter_m)) for value in bag.position_m())
            jittered.append(dataclasses.replace(bag, distance_m=distance_m, height_m=height_m, side_m=side_m))
        options = EpisodeStart(jittered, options.lead_in)
    return options


class _EpisodeSettings:
    """What both envs keep: the handshake and the episodes' settings."""

    def _adopt(self, info: ServerInfo, frames: int, smoothing_window: int, reward: Reward | None, bag_jitter_m: float) -> None:
        self.info = info
        self.frames = frames
        self.smoothing_window = smoothing_window
        self.reward = reward
        self.bag_jitter_m = bag_jitter_m
        self.feature_names = info.feature_names
        self.spec_hash = info.spec_hash
        self._scorer = EpisodeScorer(reward, info.feature_names) if reward is not None else None

    def _decision_rewards(self, features: np.ndarray) -> np.ndarray:
        """Each character's reward for the decision that played `features` [N, period, F] (0 with no reward)."""
        return self._scorer.add(features)[0] if self._scorer is not None else np.zeros(features.shape[0])


class PunchEnv(gym.Env, _EpisodeSettings):
    """One punching character in its own headless Godot process (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, *, frames: int = 50, decision_period: int = 5, smoothing_window: int = 1,
                 reward: Reward | None = None, bag_jitter_m: float = 0.0, server: TrainingServer | None = None):
        self._decision_period = decision_period
        self._owns_server = server is None
        self.server = server or TrainingServer(1, decision_period=decision_period)
        info = self.server.info
        if info.slot_count != 1:
            raise ValueError("PunchEnv drives a one-slot server; use PunchVectorEnv for more")
        self._adopt(info, frames, smoothing_window, reward, bag_jitter_m)
        self.observation_space, self.action_space = _spaces(info)

    def reset(self, *, seed: int | None = None, options: Options = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if self._owns_server and self.server.idle_expired():  # it would quit under this episode: a fresh one
            self.server.close()
            self.server = TrainingServer(1, decision_period=self._decision_period)
        start = _episode_start(options, self.info.default_bag, self.np_random, 1, self.bag_jitter_m)
        if self._scorer is not None:
            self._scorer.reset()
        lead_in = start.lead_in
        reply = self.server.reset(self.frames, bags=start.bags, smoothing_window=self.smoothing_window,
                                  lead_in=None if lead_in is None else np.asarray(lead_in, dtype=np.float32).reshape(1, -1, self.info.action_size))
        return reply.arrays["observations"][0].copy(), {"features": reply.arrays["features"][0].copy(), "bag": start.bags[0]}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = np.asarray(action, dtype=np.float32).reshape(1, -1)
        reply = self.server.step(action)
        features = reply.arrays["features"][0].copy()
        reward = float(self._decision_rewards(features[None])[0])
        info = {"features": features, "executed_action": reply.arrays["executed_actions"][0, 0].copy()}
        return (reply.arrays["observations"][0].copy(), reward, bool(reply.fields["terminated"][0]),
                bool(reply.fields["truncated"][0]), info)

    def close(self) -> None:
        self.server.close()


class PunchVectorEnv(gym.vector.VectorEnv, _EpisodeSettings):
    """K Godot processes x N characters each, stepped in lockstep (requests go to every process before any
    reply is read, so processes simulate in parallel). Episodes of all characters start and end together;
    after the last decision the next `step` resets every character (Gymnasium's next-step autoreset) and
    returns the new first observations with zero reward. The processes are started on `backend` (local
    processes or Ray workers)."""

    metadata = {"autoreset_mode": gym.vector.AutoresetMode.NEXT_STEP}

    def __init__(self, processes: int = 1, characters_per_process: int = 16, *, frames: int = 50,
                 decision_period: int = 5, smoothing_window: int = 1, reward: Reward | None = None,
                 bag_jitter_m: float = 0.0, backend: Backend = LOCAL):
        self.group = ServerGroup(processes, characters_per_process, decision_period, backend=backend)
        info = self.group.info
        self._adopt(info, frames, smoothing_window, reward, bag_jitter_m)
        self.characters_per_process = characters_per_process
        self.num_envs = processes * characters_per_process
        self.single_observation_space, self.single_action_space = _spaces(info)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self._needs_reset = True

    def reset(self, *, seed: int | None = None, options: Options = None) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(seed)
        self.group.replace_idle()  # a server idle for most of its idle timeout would quit under this episode
        start = _episode_start(options, self.info.default_bag, self.np_random, self.num_envs, self.bag_jitter_m)
        if self._scorer is not None:
            self._scorer.reset()
        bags, lead_in = start.bags, start.lead_in  # lead_in [num_envs, decisions, A]: reset_message
        n = self.characters_per_process
        replies = exchange(self.servers, [reset_message(self.frames, bags=bags[p * n:(p + 1) * n], smoothing_window=self.smoothing_window,
                                                        lead_in=None if lead_in is None else lead_in[p * n:(p + 1) * n])
                                          for p in range(len(self.servers))])
        self._needs_reset = False
        observations = np.concatenate([r.arrays["observations"] for r in replies])
        return observations, {"features": np.concatenate([r.arrays["features"] for r in replies])}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if self._needs_reset:
            observations, info = self.reset()
            zeros = np.zeros(self.num_envs, dtype=bool)
            return observations, np.zeros(self.num_envs), zeros, zeros.copy(), info
        actions = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)
        n = self.characters_per_process
        replies = exchange(self.servers, [step_message(actions[p * n:(p + 1) * n]) for p in range(len(self.servers))])
        features = np.concatenate([r.arrays["features"] for r in replies])
        terminated = np.concatenate([r.fields["terminated"] for r in replies]).astype(bool)
        truncated = np.concatenate([r.fields["truncated"] for r in replies]).astype(bool)
        rewards = self._decision_rewards(features)
        self._needs_reset = bool(np.all(terminated | truncated))
        return np.concatenate([r.arrays["observations"] for r in replies]), rewards, terminated, truncated, {"features": features}

    @property
    def servers(self) -> list[ServerConnection]:
        return self.group.servers

    def restart(self) -> None:
        """Replaces the Godot processes with fresh ones (after one crashed); the next step starts new episodes."""
        self.group.restart()
        self._needs_reset = True

    def close_extras(self, **kwargs: Any) -> None:
        self.group.close()

    def __enter__(self) -> PunchVectorEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def make_vector_env(num_envs: int, *, characters_per_process: int | None = None, **kwargs: Any) -> PunchVectorEnv:
    """`gym.make_vec("punch/Punch-v0", num_envs=M)`: M characters, in processes of `characters_per_process`
    (default: all in one process)."""
    per_process = characters_per_process or num_envs
    if num_envs % per_process:
        raise ValueError(f"num_envs ({num_envs}) must be a multiple of characters_per_process ({per_process})")
    return PunchVectorEnv(num_envs // per_process, per_process, **kwargs)
