"""Rewards: Python functions of the per-frame features, the only thing a user writes to get a new motion.

A reward receives a `Frames` view of features shaped [..., frames, F] (batched: every rollout at once) and
returns either one array of per-frame rewards [..., frames] or a dict of named terms of that shape (their
sum is the reward; each term is logged on its own). Frames the physics guard flagged earn nothing.

    # my_rewards.py, used as: punch search --reward my_rewards.py:jab
    def jab(f):
        near = np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2
        return {"forward": near * 10.0 * f["fist_r_vel_z"], "soon": -0.01 * np.ones_like(near)}

The presets are the paper's Table 2 and an uppercut, with d the distance from the right fist to the bag's
centre of mass and v the right fist's velocity (z toward the bag, x the character's left, y up).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from punch_trainer.options import BOUNDS
from punch_trainer.policy_file import FRAMES, REWARD
from punch_trainer.reward.sandbox import Frames as Frames
from punch_trainer.reward.sandbox import IsolatedFunction, result_terms
from punch_trainer.reward.sandbox import RewardError as RewardError
from punch_trainer.reward.sandbox import Terms as Terms
from punch_trainer.reward.style import CONTACT_IMPULSE_NS, Style
from punch_trainer.scene import GUARD_ELBOW_BEND_DEG, shoulder_positions


def first_right_contact(features: np.ndarray, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Of features [..., frames, F]: whether the right fist touched the bag, and the first frame it did (0 if never)."""
    col = names.index
    impulse = np.linalg.norm(features[..., col("fist_r_impulse_x"):col("fist_r_impulse_z") + 1], axis=-1)
    touched = impulse > CONTACT_IMPULSE_NS
    return touched.any(axis=-1), touched.argmax(axis=-1)


RewardFunction = Callable[[Frames], "np.ndarray | Terms"]


def _near(f: Frames) -> np.ndarray:
    return np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2


def straight(f: Frames) -> Terms:
    """(a) straight: max(0, 0.3 - d)^2 * 10 * v_z."""
    return {"forward": _near(f) * 10.0 * f["fist_r_vel_z"]}


def hook(f: Frames) -> Terms:
    """(c) hook: max(0, 0.3 - d)^2 * 10 * (v_z + 0.75 v_x)."""
    near = _near(f)
    return {"forward": near * 10.0 * f["fist_r_vel_z"], "sideways": near * 10.0 * 0.75 * f["fist_r_vel_x"]}


def swing(f: Frames) -> Terms:
    """(d) swing: max(0, 0.3 - d)^2 * 500 * (v_z + 0.5 v_x)."""
    near = _near(f)
    return {"forward": near * 500.0 * f["fist_r_vel_z"], "sideways": near * 500.0 * 0.5 * f["fist_r_vel_x"]}


def hook_landing(f: Frames) -> Terms:
    """The hook that lands (not the paper's): the `hook` reward's terms plus 5 times the impulse the fist gives the bag
    along the hook's direction (forward and 0.75 sideways, N s), as the uppercut's lift: sweeping past the bag earns
    less than landing on it. The lead hook's: from the lead side's guard the fist starts near the line to the bag, and
    the `hook` reward alone taught no punch there (experiments/notebook.md)."""
    terms = hook(f)
    return {**terms, "landing": 5.0 * (f["fist_r_impulse_z"] + 0.75 * f["fist_r_impulse_x"])}


def along_target(f: Frames) -> tuple[np.ndarray, np.ndarray]:
    """The horizontal unit vector (x, z) from the right shoulder to the bag; the shoulder is the one the naturalness
    report reads (`scene.shoulder_positions`), so a reward and the measure read one geometry."""
    shoulder = shoulder_positions(f.features.reshape(-1, len(f.names)), f.names.index).reshape(*f.features.shape[:-1], 3)
    dx, dz = f["bag_pos_x"] - shoulder[..., 0], f["bag_pos_z"] - shoulder[..., 2]
    length = np.maximum(np.hypot(dx, dz), 1e-6)
    return dx / length, dz / length


def elbow_bent(f: Frames, none_deg: float, all_deg: float) -> np.ndarray:
    """0 with the right elbow bent `none_deg` or less, 1 from `all_deg`, linear between."""
    bend_deg = GUARD_ELBOW_BEND_DEG - np.degrees(f["angle_elbow_r_extension"])
    return np.asarray(np.clip((bend_deg - none_deg) / (all_deg - none_deg), 0.0, 1.0))


def frame_before(values: np.ndarray) -> np.ndarray:
    """Each frame's value the frame before (the first frame's own): the naturalness report reads a fist's approach
    and rise the frame before contact, since the contact itself turns the fist."""
    return np.concatenate([values[..., :1], values[..., :-1]], axis=-1)


def hook_bent(f: Frames) -> Terms:
    """The boxer's hook (not the paper's): the fist sweeps in from the side with the elbow bent. With a and c the right
    fist's horizontal velocity along and across the line from its shoulder to the bag (across: toward the body's
    middle), max(0, 0.3 - d)^2 * 10 * (a + 1.5 c), plus 5 times the impulse the fist lands with along the same a + 1.5 c,
    which counts only with the elbow bent: none at 50 degrees or less, all of it from 80 (docs/moves.md asks a hook's
    fist to arrive at least 35 degrees off that line with the elbow bent 70-120). At a given speed the best direction
    lies 56 degrees off the line. The `hook` reward's fist arrives 16 degrees off the line with the elbow at 56
    degrees from the lead hand's guard: a jab (experiments/notebook.md, "A hook that sweeps with the elbow bent")."""
    ux, uz = along_target(f)

    def sweep(x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return np.asarray((x * ux + z * uz) + 1.5 * (x * uz - z * ux))

    return {"sweep": _near(f) * 10.0 * sweep(f["fist_r_vel_x"], f["fist_r_vel_z"]),
            "landing": 5.0 * elbow_bent(f, 50.0, 80.0) * sweep(f["fist_r_impulse_x"], f["fist_r_impulse_z"])}


def hook_outside(f: Frames) -> Terms:
    """`hook_bent` whose landing also counts only for a fist coming from outside the line from its shoulder to the bag:
    none at 20 degrees off it or less, all of it from 35 (the fist's horizontal velocity the frame before, as the
    naturalness report reads the approach: the contact itself turns the fist). Asked of a trained lead hook, whose fist
    stands near the bag's line in the stance's guard (experiments/notebook.md, "A hook that sweeps with the elbow
    bent")."""
    terms = hook_bent(f)
    ux, uz = along_target(f)
    vx, vz = frame_before(f["fist_r_vel_x"]), frame_before(f["fist_r_vel_z"])
    angle_deg = np.degrees(np.arctan2(vx * uz - vz * ux, vx * ux + vz * uz))
    outside = np.clip((angle_deg - 20.0) / 15.0, 0.0, 1.0)
    return {**terms, "landing": terms["landing"] * outside}


def straight_landing(f: Frames) -> Terms:
    """The straight that lands (not the paper's): the `straight` reward's term plus 5 times the forward impulse the
    fist lands with (N s), as `hook_landing`: the jab's, from the lead side's guard, where the `straight` reward alone
    taught no punch (experiments/notebook.md)."""
    return {**straight(f), "landing": 5.0 * f["fist_r_impulse_z"]}


def uppercut(f: Frames) -> Terms:
    """The uppercut (not the paper's): max(0, 0.3 - d)^2 * 10 * (v_z + v_y), the fist coming in and up, plus 5 times
    the upward impulse the fist gives the bag (N s): rising near the bag without touching it earns less than lifting
    it."""
    near = _near(f)
    return {"forward": near * 10.0 * f["fist_r_vel_z"], "up": near * 10.0 * f["fist_r_vel_y"],
            "lift": 5.0 * f["fist_r_impulse_y"]}


def uppercut_bent(f: Frames, flat_landing: float = 0.25) -> Terms:
    """The boxer's uppercut (not the paper's): the fist rises into the target with the elbow bent. With a the right
    fist's horizontal velocity along the line from its shoulder to the bag, 10 max(0, 0.3 - d)^2 max(0, a + 1.5 v_y),
    plus 5 times the impulse it lands with along the same a + 1.5 y: `flat_landing` of it however the fist comes, the
    rest only with the elbow bent (none at 40 degrees, all from 70) and the fist rising (the upward share of its
    velocity the frame before: none at 0.35, all from 0.6; docs/moves.md asks at least 0.5 and 60-120 degrees). Taught
    from scratch it made A2C keep the fist away; asked of a trained `uppercut`, it reshapes the punch
    (experiments/notebook.md, "An uppercut that rises with the elbow bent")."""
    ux, uz = along_target(f)
    vx, vy, vz = f["fist_r_vel_x"], f["fist_r_vel_y"], f["fist_r_vel_z"]
    share = vy / np.maximum(np.sqrt(vx ** 2 + vy ** 2 + vz ** 2), 0.5)
    rising = np.clip((frame_before(share) - 0.35) / 0.25, 0.0, 1.0)
    landing = f["fist_r_impulse_x"] * ux + f["fist_r_impulse_z"] * uz + 1.5 * f["fist_r_impulse_y"]
    return {"rise": _near(f) * 10.0 * np.maximum(0.0, vx * ux + vz * uz + 1.5 * vy),
            "landing": 5.0 * (flat_landing + (1.0 - flat_landing) * elbow_bent(f, 40.0, 70.0) * rising) * landing}


def uppercut_gated(f: Frames) -> Terms:
    """`uppercut_bent` with none of its landing counted unless the fist rises with the elbow bent: the last stage of
    the uppercuts' recipes, after `uppercut_bent` has moved the punch toward that shape."""
    return uppercut_bent(f, flat_landing=0.0)


def uppercut_rising(f: Frames) -> Terms:
    """`uppercut_gated` whose approach near the bag counts only while the fist rises too (none at an upward share of
    its velocity of 0.35, all from 0.6, as its landing): the lead uppercut's last stage, where the approach term alone
    had taught a fist that comes in level (experiments/notebook.md, "A braced guard": "The lead uppercut's rise, all of it gated")."""
    terms = uppercut_gated(f)
    vx, vy, vz = f["fist_r_vel_x"], f["fist_r_vel_y"], f["fist_r_vel_z"]
    share = vy / np.maximum(np.sqrt(vx ** 2 + vy ** 2 + vz ** 2), 0.5)
    return {**terms, "rise": terms["rise"] * np.clip((share - 0.35) / 0.25, 0.0, 1.0)}


@dataclass(frozen=True)
class Reward:
    """A reward, the episode length it is meant for, and the trajectory search's sigma clip for it."""

    name: str
    function: RewardFunction
    frames: int
    # How fast TTR may narrow its search (see punch_trainer.learn.search). The swing's half-circle sweep lies far
    # from the guard pose and needs exploration to last longer: measured over 2 seeds at 6,400 rollouts,
    # 0.1 gave a best return of 338 against 251 for 0.2, while 0.2 was better for hook and straight100.
    search_clip_epsilon: float = 0.2
    style: Style | None = None
    """the motion style the product adds to the reward (reward/style.py); None: the reward alone"""


PRESETS = {
    "straight": Reward("straight", straight, 50),
    "straight100": Reward("straight100", straight, 100),
    "hook": Reward("hook", hook, 50),
    "swing": Reward("swing", swing, 50, search_clip_epsilon=0.1),
    "uppercut": Reward("uppercut", uppercut, 50),
    "hook_landing": Reward("hook_landing", hook_landing, 50),
    "straight_landing": Reward("straight_landing", straight_landing, 50),
    "hook_bent": Reward("hook_bent", hook_bent, 50),
    "hook_outside": Reward("hook_outside", hook_outside, 50),
    "uppercut_bent": Reward("uppercut_bent", uppercut_bent, 50),
    "uppercut_gated": Reward("uppercut_gated", uppercut_gated, 50),
    "uppercut_rising": Reward("uppercut_rising", uppercut_rising, 50),
}


def load_reward(spec: str, frames: int | None = None, style: Style | None = None) -> Reward:
    """A preset name, `path/to/file.py:function` or `package.module:function`; `frames` overrides the
    preset's episode length (default 50 for user rewards); `style`: the motion style added to it (reward/style.py)."""
    if spec in PRESETS:
        preset = PRESETS[spec]
        return Reward(preset.name, preset.function, frames or preset.frames, preset.search_clip_epsilon, style)
    if ":" not in spec:
        raise RewardError(f"unknown reward '{spec}': use a preset ({', '.join(PRESETS)}) or FILE.py:FUNCTION")
    location, function_name = spec.rsplit(":", 1)
    if location.endswith(".py"):
        path = Path(location)
        if not path.is_file():
            raise RewardError(f"reward file not found: {path}")
        location = str(path.resolve())
    # The user's code is imported and called in a worker process, never in the trainer (reward/sandbox.py).
    function = IsolatedFunction(spec, location, function_name, reward_time_limit_s)
    function.load()
    return Reward(spec, function, frames or 50, style=style)


def reward_fingerprint(reward: Reward) -> str:
    """What a run directory records of its reward, so that a resume can tell it is the same code: a preset's
    name, or the SHA-256 of the user's source as the worker imported it."""
    if isinstance(reward.function, IsolatedFunction):
        return f"sha256:{reward.function.source_sha256}"
    preset = PRESETS.get(reward.name)
    if preset is not None and preset.function is reward.function:
        return f"preset:{reward.name}"
    code = getattr(reward.function, "__code__", None)
    digest = hashlib.sha256(code.co_code).hexdigest() if code is not None else ""
    return f"python:{getattr(reward.function, '__qualname__', type(reward.function).__name__)}:{digest}"


def metadata_reward(metadata: dict[str, str], source: str, explicit: str | None = None) -> Reward:
    """The reward to score a policy's punches with: `explicit` (the user's `--reward`, which may name their
    own code) when given, else the policy's `punch_reward` metadata, which is only ever a preset name: a model
    file is data and never chooses code to run."""
    if FRAMES not in metadata:
        raise RewardError(f"{source}: its metadata has no {FRAMES}")
    frames = metadata[FRAMES]
    limits = BOUNDS["frames"]
    if not (frames.isascii() and frames.isdigit() and len(frames) < 8) or limits.refuses(int(frames)):
        raise RewardError(f"{source}: its metadata's {FRAMES} {frames[:40]!r} is not a frame count ({limits.describe()})")
    if explicit:
        return load_reward(explicit, int(frames))
    name = metadata.get(REWARD)
    if not name:
        raise RewardError(f"{source} names no reward in its metadata; pass --reward")
    if name not in PRESETS:
        raise RewardError(f"{source} names the reward {name!r}, which is not a built-in preset ({', '.join(PRESETS)}); "
                          f"a policy's metadata never chooses code to run: pass --reward {name} if you trust it")
    return load_reward(name, int(frames))


def evaluate(reward: Reward, features: np.ndarray, feature_names: list[str]) -> Terms:
    """Per-frame reward terms [..., frames] of `features` [..., frames, F], with guarded frames zeroed.
    Raises RewardError naming the reward when it raises, exits, hangs past its time limit, returns the wrong
    shape, NaN, or anything but real numbers."""
    # A preset sees a read-only view; a user's reward (IsolatedFunction) gets a copy in its own process.
    view = np.asarray(features).view()
    view.flags.writeable = False
    frames = Frames(view, feature_names)
    if isinstance(reward.function, IsolatedFunction):
        result: object = reward.function(frames)
    else:
        try:
            result = reward.function(frames)
        except Exception as error:  # a Python function handed to Reward may fail in any way; say which and why
            raise RewardError(f"reward '{reward.name}' raised {type(error).__name__}: {error}") from error
    terms = result_terms(reward.name, result, features.shape[:-1])
    guarded = frames["exploit_flags"] != 0
    terms = {name: np.where(guarded, 0.0, values) for name, values in terms.items()}
    return reward.style.apply(terms, frames.__getitem__) if reward.style is not None else terms


def _time_limit_s(text: str | None, default_s: float = 60.0) -> float:
    try:
        value = float(text) if text else default_s
    except ValueError:
        raise RewardError(f"PUNCH_REWARD_TIME_LIMIT_S={text!r} is not a number of seconds") from None
    if not 0 < value <= 86400:
        raise RewardError(f"PUNCH_REWARD_TIME_LIMIT_S={text!r} must be more than 0 and at most 86400 s")
    return value


REWARD_TIME_LIMIT_S: float | None = None
"""Longest one reward evaluation may take (a batch of trajectories), seconds; None: PUNCH_REWARD_TIME_LIMIT_S,
else 60 s. A user's reward past it has its worker killed."""


def reward_time_limit_s() -> float:
    """REWARD_TIME_LIMIT_S, read at each call (tests set it)."""
    return REWARD_TIME_LIMIT_S or _time_limit_s(os.environ.get("PUNCH_REWARD_TIME_LIMIT_S"))


def total(terms: Terms) -> np.ndarray:
    """The reward: the sum of the terms, [..., frames]."""
    return np.asarray(sum(terms.values()))


def score_terms(reward: Reward, features: np.ndarray, feature_names: list[str]) -> tuple[np.ndarray, Terms]:
    """The one scoring recipe: the return of every trajectory in `features` [..., frames, F] (the reward summed
    over its frames), shape [...], with the per-frame terms it came from."""
    terms = evaluate(reward, features, feature_names)
    return total(terms).sum(axis=-1), terms


def score(reward: Reward, features: np.ndarray, feature_names: list[str]) -> np.ndarray:
    """The return of every trajectory in `features` [..., frames, F]: shape [...]. Scoring an episode's frames
    gives its return; a decision's reward comes from `EpisodeScorer`, which knows the frames before it."""
    return score_terms(reward, features, feature_names)[0]


class EpisodeScorer:
    """Scores episodes decision by decision, as they are played: each decision's reward (and terms) of its own
    frames [..., period, F]. A reward alone is per frame, so a decision's frames are scored on their own, as
    always. A style (reward/style.py) discounts by the cost of the whole episode so far and measures the guard from
    the episode's first frame, so then the episode so far is scored and the decision's frames taken from it: the
    decisions' rewards add up to exactly the episode's return, as the search scores it."""

    def __init__(self, reward: Reward, feature_names: list[str]):
        self.reward = reward
        self.feature_names = feature_names
        self._episode: list[np.ndarray] = []

    def reset(self) -> None:
        """A new episode starts with the next `add`."""
        self._episode = []

    def add(self, frames: np.ndarray) -> tuple[np.ndarray, Terms]:
        """The reward [...] of the decision that played `frames` [..., period, F], and its terms summed over them."""
        if self.reward.style is None:
            returns, terms = score_terms(self.reward, frames, self.feature_names)
            return returns, {name: values.sum(axis=-1) for name, values in terms.items()}
        self._episode.append(np.asarray(frames))
        period = frames.shape[-2]
        terms = evaluate(self.reward, np.concatenate(self._episode, axis=-2), self.feature_names)
        terms = {name: values[..., -period:] for name, values in terms.items()}
        return total(terms).sum(axis=-1), {name: values.sum(axis=-1) for name, values in terms.items()}


def decision_rewards(reward: Reward, features: np.ndarray, feature_names: list[str], decision_period: int) -> np.ndarray:
    """Each decision's reward [..., decisions] of a whole episode's `features` [..., frames, F]."""
    scorer = EpisodeScorer(reward, feature_names)
    decisions = features.shape[-2] // decision_period
    return np.stack([scorer.add(features[..., d * decision_period:(d + 1) * decision_period, :])[0]
                     for d in range(decisions)], axis=-1)
