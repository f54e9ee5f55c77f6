"""Rewards: Python functions of the per-frame features, the only thing a user writes to get a new motion.

A reward receives a `Frames` view of features shaped [..., frames, F] (batched: every rollout at once) and
returns either one array of per-frame rewards [..., frames] or a dict of named terms of that shape (their
sum is the reward; each term is logged on its own). Frames the physics guard flagged earn nothing.

    # my_rewards.py, used as: punch search --reward my_rewards.py:uppercut
    def uppercut(f):
        near = np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2
        return {"up": near * 10.0 * f["fist_r_vel_y"], "forward": near * 5.0 * f["fist_r_vel_z"]}

The presets are the paper's Table 2, with d the distance from the right fist to the bag's centre of mass
and v the right fist's velocity (z toward the bag, x the character's left).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from punch_trainer.errors import PunchError

CONTACT_IMPULSE_NS = 1e-3
"""A right-fist impulse on the bag above this (N s) counts as contact."""


def first_right_contact(features: np.ndarray, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Of features [..., frames, F]: whether the right fist touched the bag, and the first frame it did (0 if never)."""
    col = names.index
    impulse = np.linalg.norm(features[..., col("fist_r_impulse_x"):col("fist_r_impulse_z") + 1], axis=-1)
    touched = impulse > CONTACT_IMPULSE_NS
    return touched.any(axis=-1), touched.argmax(axis=-1)


Terms = dict[str, np.ndarray]
RewardFunction = Callable[["Frames"], "np.ndarray | Terms"]


class RewardError(PunchError):
    """A reward could not be loaded, raised, or returned something that is not a per-frame reward."""


class Frames:
    """Named access to features [..., frames, F]: `f["fist_r_vel_z"]` is [..., frames]."""

    def __init__(self, features: np.ndarray, feature_names: list[str]):
        self.features = features
        self._index = {name: i for i, name in enumerate(feature_names)}

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.features[..., self._index[name]]
        except KeyError:
            raise KeyError(f"no feature '{name}'; features are: {', '.join(self._index)}") from None

    @property
    def names(self) -> list[str]:
        return list(self._index)


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


PRESETS = {
    "straight": Reward("straight", straight, 50),
    "straight100": Reward("straight100", straight, 100),
    "hook": Reward("hook", hook, 50),
    "swing": Reward("swing", swing, 50, search_clip_epsilon=0.1),
}


def load_reward(spec: str, frames: int | None = None) -> Reward:
    """A preset name, `path/to/file.py:function` or `package.module:function`; `frames` overrides the
    preset's episode length (default 50 for user rewards)."""
    if spec in PRESETS:
        preset = PRESETS[spec]
        return Reward(preset.name, preset.function, frames or preset.frames, preset.search_clip_epsilon)
    if ":" not in spec:
        raise RewardError(f"unknown reward '{spec}': use a preset ({', '.join(PRESETS)}) or FILE.py:FUNCTION")
    location, function_name = spec.rsplit(":", 1)
    try:
        if location.endswith(".py"):
            path = Path(location)
            if not path.is_file():
                raise RewardError(f"reward file not found: {path}")
            module_spec = importlib.util.spec_from_file_location(f"punch_user_reward_{path.stem}", path)
            if module_spec is None or module_spec.loader is None:
                raise RewardError(f"reward file {path} cannot be imported as a Python module")
            module = importlib.util.module_from_spec(module_spec)
            module_spec.loader.exec_module(module)
        else:
            module = importlib.import_module(location)
    except RewardError:
        raise
    except Exception as error:  # the user's module may fail in any way; say so, with its message
        raise RewardError(f"reward '{spec}': importing {location} failed: {type(error).__name__}: {error}") from error
    function = getattr(module, function_name, None)
    if not callable(function):
        raise RewardError(f"reward '{spec}': {location} has no function '{function_name}'")
    return Reward(spec, function, frames or 50)


def metadata_reward(metadata: dict[str, str], source: str, explicit: str | None = None) -> Reward:
    """The reward to score a policy's punches with: `explicit` (the user's `--reward`, which may name their
    own code) when given, else the policy's `punch_reward` metadata, which is only ever a preset name: a model
    file is data and never chooses code to run."""
    frames = metadata.get("punch_frames", "50")
    if not frames.isdigit() or int(frames) == 0:  # its range is the game's to check (punch_core::spec)
        raise RewardError(f"{source}: its metadata's punch_frames {frames!r} is not a frame count")
    if explicit:
        return load_reward(explicit, int(frames))
    name = metadata.get("punch_reward")
    if not name:
        raise RewardError(f"{source} names no reward in its metadata; pass --reward")
    if name not in PRESETS:
        raise RewardError(f"{source} names the reward {name!r}, which is not a built-in preset ({', '.join(PRESETS)}); "
                          f"a policy's metadata never chooses code to run: pass --reward {name} if you trust it")
    return load_reward(name, int(frames))


def evaluate(reward: Reward, features: np.ndarray, feature_names: list[str]) -> Terms:
    """Per-frame reward terms [..., frames] of `features` [..., frames, F], with guarded frames zeroed.
    Raises RewardError naming the reward when it raises, returns the wrong shape, or returns NaN."""
    # The reward sees a read-only view: writing into it would corrupt the dataset and the report silently.
    view = np.asarray(features).view()
    view.flags.writeable = False
    frames = Frames(view, feature_names)
    result = _call_guarded(reward, frames)
    if isinstance(result, dict):
        terms = result
    elif isinstance(result, (np.ndarray, float, int, np.floating)):
        terms = {"reward": result}
    else:
        raise RewardError(f"reward '{reward.name}' returned {type(result).__name__}; it must return an array of "
                          "per-frame rewards or a dict of such arrays")
    if not terms:
        raise RewardError(f"reward '{reward.name}' returned an empty dict; it must name at least one term")
    expected = features.shape[:-1]
    guarded = frames["exploit_flags"] != 0
    out = {}
    for name, values in terms.items():
        values = np.asarray(values, dtype=np.float64)
        if values.shape != expected:
            raise RewardError(f"reward '{reward.name}' term '{name}' has shape {values.shape}; expected {expected} (one value per frame)")
        if not np.all(np.isfinite(values)):
            raise RewardError(f"reward '{reward.name}' term '{name}' returned NaN or infinity")
        out[name] = np.where(guarded, 0.0, values)
    return out


def _time_limit_s(text: str | None, default_s: float = 60.0) -> float:
    try:
        value = float(text) if text else default_s
    except ValueError:
        raise RewardError(f"PUNCH_REWARD_TIME_LIMIT_S={text!r} is not a number of seconds") from None
    if not value > 0:
        raise RewardError(f"PUNCH_REWARD_TIME_LIMIT_S={text!r} must be positive")
    return value


REWARD_TIME_LIMIT_S: float | None = None
"""Longest one reward evaluation may take (a batch of trajectories), seconds; None: PUNCH_REWARD_TIME_LIMIT_S,
else 60 s."""


class _RewardExit(BaseException):
    """Raised in place of exiting the process when a reward calls os._exit."""


class _RewardTimeout(BaseException):
    """Raised by the timer signal when a reward runs past its time limit (not an Exception, so the reward's
    own `except Exception` cannot swallow it, and its own TimeoutErrors stay its own)."""


def _call_guarded(reward: Reward, frames: Frames) -> object:
    """Calls the user's reward: its exceptions, `sys.exit` and `os._exit` become a RewardError naming it, and a
    call longer than REWARD_TIME_LIMIT_S is stopped (in the main thread, where a timer signal can interrupt
    it; elsewhere it is only measured)."""
    def refuse_exit(code: int) -> None:
        raise _RewardExit(code)

    def too_slow(_signum: int, _frame: object) -> None:
        raise _RewardTimeout

    limit_s = REWARD_TIME_LIMIT_S or _time_limit_s(os.environ.get("PUNCH_REWARD_TIME_LIMIT_S"))
    timed = threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")
    previous_handler = signal.signal(signal.SIGALRM, too_slow) if timed else None
    real_exit, os._exit = os._exit, refuse_exit  # type: ignore[assignment]
    started = time.monotonic()
    try:
        if timed:
            signal.setitimer(signal.ITIMER_REAL, limit_s)
        result = reward.function(frames)
    except _RewardTimeout:
        raise RewardError(f"reward '{reward.name}' took longer than {limit_s:g} s on one batch and was "
                          "stopped (set PUNCH_REWARD_TIME_LIMIT_S to allow more)") from None
    except (SystemExit, _RewardExit) as error:
        raise RewardError(f"reward '{reward.name}' tried to exit the process (exit code {error.args[0] if error.args else 0}); "
                          "a reward must return its values") from None
    except Exception as error:  # the user's code may fail in any way; say which reward and why
        raise RewardError(f"reward '{reward.name}' raised {type(error).__name__}: {error}") from error
    finally:
        os._exit = real_exit
        if timed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous_handler)
    if time.monotonic() - started > limit_s:
        raise RewardError(f"reward '{reward.name}' took longer than {limit_s:g} s on one batch")
    return result


def total(terms: Terms) -> np.ndarray:
    """The reward: the sum of the terms, [..., frames]."""
    return np.asarray(sum(terms.values()))


def score_terms(reward: Reward, features: np.ndarray, feature_names: list[str]) -> tuple[np.ndarray, Terms]:
    """The one scoring recipe: the return of every trajectory in `features` [..., frames, F] (the reward summed
    over its frames), shape [...], with the per-frame terms it came from."""
    terms = evaluate(reward, features, feature_names)
    return total(terms).sum(axis=-1), terms


def score(reward: Reward, features: np.ndarray, feature_names: list[str]) -> np.ndarray:
    """The return of every trajectory in `features` [..., frames, F]: shape [...]. Scoring a decision's frames
    gives that decision's reward; scoring an episode's, its return."""
    return score_terms(reward, features, feature_names)[0]
