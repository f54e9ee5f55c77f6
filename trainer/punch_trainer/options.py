"""The bounds of every option of every command, checked in one place: `check_options` refuses a value of the
wrong type, a float that is NaN or infinite, or a number outside its bounds, before any work starts, and
whether it came from the command line (`cli/arguments.py`) or a run's config.json (`learn/checkpoint.py`).

A field's bounds are its own (`dataclasses.field(metadata=bounds(...))`) or else those of its name in
`BOUNDS` (the same name means the same thing in every `*Args`: `seed`, `episodes`, `characters`); a numeric
field with neither is refused by `tests/python/test_options.py`, so no option goes unchecked. The help of an
option states its bounds.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from punch_trainer.errors import PunchError


class OptionError(PunchError):
    """An option's value (from the command line or a run's config.json) is of the wrong type or out of bounds."""


@dataclass(frozen=True)
class Bounds:
    """Inclusive bounds of a number, or of every item of a list; `low_exclusive`: the low bound itself is refused."""

    low: float | None = None
    high: float | None = None
    low_exclusive: bool = False
    max_items: int | None = None
    """most items of a list option"""

    def describe(self, sequence: bool = False) -> str:
        parts = []
        if self.low is not None:
            parts.append(f"{'more than' if self.low_exclusive else 'at least'} {_number(self.low)}")
        if self.high is not None:
            parts.append(f"at most {_number(self.high)}")
        if sequence and self.max_items is not None:
            parts.append(f"at most {self.max_items} values")
        return ", ".join(parts)

    def refuses(self, value: float) -> bool:
        return bool((self.low is not None and (value <= self.low if self.low_exclusive else value < self.low))
                    or (self.high is not None and value > self.high))


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e15 else f"{value:g}"


def bounds(low: float | None = None, high: float | None = None, *, low_exclusive: bool = False,
           max_items: int | None = None) -> dict[str, Bounds]:
    """Field metadata: `seed: int = field(default=0, metadata=bounds(0, 2**32 - 1))`."""
    return {"bounds": Bounds(low, high, low_exclusive, max_items)}


SIGMA = Bounds(0.0, 1.0, max_items=100)
"""A noise sigma: PunchController clamps to 0..1, so a value outside is refused rather than played as another."""
SEED = Bounds(0, 2**32 - 1, max_items=100)
ITERATIONS = Bounds(1, 100_000)
EVERY_UPDATES = Bounds(0, 100_000)
"""how often, in updates, something is done along a run (0: never)"""
ROLLOUTS = Bounds(1, 4096)
CHARACTERS = Bounds(1, 4096, max_items=32)
SHARE = Bounds(0.0, 1.0)
SECONDS = Bounds(0.0, 30 * 86400.0)

BOUNDS: dict[str, Bounds] = {
    "seed": SEED, "seeds": SEED,
    "sigmas": SIGMA,
    "frames": Bounds(1, 1200),  # ten seconds at 120 Hz
    "iterations": ITERATIONS, "search_iterations": ITERATIONS, "volume_search_iterations": ITERATIONS,
    "plateau_iterations": Bounds(0, 100_000),
    "rollouts": ROLLOUTS, "search_rollouts": ROLLOUTS, "volume_search_rollouts": ROLLOUTS,
    "updates": ITERATIONS, "a2c_updates": ITERATIONS, "snapshot_every": EVERY_UPDATES, "a2c_snapshot_every": EVERY_UPDATES,
    "epochs": Bounds(1, 1_000_000), "pretrain_epochs": Bounds(1, 1_000_000),
    "episodes": Bounds(1, 100_000),
    "noisy_episodes": Bounds(0, 1000),
    "placements": Bounds(1, 10_000), "validation_placements": Bounds(1, 10_000),
    "characters": CHARACTERS, "a2c_characters": CHARACTERS, "characters_per_process": Bounds(1, 1024),
    "characters_per_world": Bounds(1, 256),
    "processes": Bounds(1, 256, max_items=32),
    "decision_period": Bounds(1, 120),
    "smoothing_window": Bounds(1, 100),
    "noise_decisions": Bounds(-1, 10_000),  # -1: every decision
    "batch": Bounds(1, 4096), "batches": Bounds(1, 10_000),
    "lead_in_every": Bounds(0, 10_000),
    "sigma_init": Bounds(0.0, 10.0, low_exclusive=True), "search_sigma_init": Bounds(0.0, 10.0, low_exclusive=True),
    "initial_sigma": Bounds(0.0, 1.0, low_exclusive=True),
    "sigma_min": Bounds(0.0, 10.0), "sigma_floor": SIGMA, "a2c_sigma_floor": SIGMA,
    "clip_epsilon": Bounds(0.0, 1.0, low_exclusive=True), "clip": Bounds(0.0, 10.0, low_exclusive=True),
    "learning_rate": Bounds(0.0, 1.0, low_exclusive=True),
    "gamma": SHARE, "gae_lambda": SHARE,
    "entropy_coef": Bounds(0.0, 100.0), "value_coef": Bounds(0.0, 100.0),
    "moving_share": SHARE, "default_share": SHARE, "after_punch_share": SHARE, "recovering_share": SHARE,
    "stance_share": SHARE,
    "time_budget_s": SECONDS, "a2c_time_budget_s": SECONDS,
    "timeout_s": Bounds(0.0, 7 * 86400.0, low_exclusive=True),
    "seconds": Bounds(0.0, 600.0, low_exclusive=True),
    "lead_s": Bounds(0.0, 10.0),
    "width": Bounds(16, 7680), "height": Bounds(16, 4320),
    "grid": Bounds(1, 50),
}


def field_bounds(field: dataclasses.Field[Any]) -> Bounds | None:
    """The bounds of a dataclass field: its own metadata's, else its name's in BOUNDS."""
    own = field.metadata.get("bounds")
    return own if isinstance(own, Bounds) else BOUNDS.get(field.name)


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _check_number(where: str, value: Any, kind: type, limits: Bounds | None, sequence: bool) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (kind is int and not isinstance(value, int)):
        raise OptionError(f"{where} {value!r}: must be {'a whole number' if kind is int else 'a number'}")
    if not math.isfinite(value):
        raise OptionError(f"{where} {value!r}: must be a finite number")
    if limits is not None and limits.refuses(value):
        raise OptionError(f"{where} {value!r}: must be {limits.describe(sequence)}")


def _item_type(annotation: Any) -> tuple[Any, bool]:
    """The type of a field's value (or of each item of a list or tuple) and whether it is a sequence."""
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        members = [m for m in typing.get_args(annotation) if m is not type(None)]
        annotation = members[0] if len(members) == 1 else annotation
    if typing.get_origin(annotation) in (list, tuple):
        return typing.get_args(annotation)[0], True
    return annotation, False


def check_options(args: Any, source: str = "") -> None:
    """Refuses, with an OptionError naming the option, any field of the dataclass `args` of the wrong type,
    NaN or infinite, or outside its bounds. `source` says where the values came from (a config.json)."""
    hints = typing.get_type_hints(type(args))
    for field in dataclasses.fields(args):
        value = getattr(args, field.name)
        where = f"{source}: {field.name}" if source else _flag(field.name)
        annotation = hints[field.name]
        if value is None:
            if type(None) not in typing.get_args(annotation):
                raise OptionError(f"{where} must be given")
            continue
        kind, sequence = _item_type(annotation)
        limits = field_bounds(field)
        items = value if sequence else [value]
        if sequence:
            if not isinstance(value, (list, tuple)) or not value:
                raise OptionError(f"{where} {value!r}: must be one or more values")
            if limits is not None and limits.max_items is not None and len(value) > limits.max_items:
                raise OptionError(f"{where}: {len(value)} values; at most {limits.max_items}")
        for item in items:
            if kind in (int, float):
                _check_number(where, item, kind, limits, sequence)
            elif kind is bool and not isinstance(item, bool):
                raise OptionError(f"{where} {item!r}: must be true or false")
            elif kind is str and not isinstance(item, str):
                raise OptionError(f"{where} {item!r}: must be text")
            elif kind is Path and not isinstance(item, (str, Path)):
                raise OptionError(f"{where} {item!r}: must be a path")
            elif typing.get_origin(kind) is typing.Literal and item not in typing.get_args(kind):
                raise OptionError(f"{where} {item!r}: must be one of {', '.join(map(str, typing.get_args(kind)))}")
        if field.name == "grid" and isinstance(value, str):
            _check_grid_text(where, value, limits)


def _check_grid_text(where: str, text: str, limits: Bounds | None) -> None:
    """A grid written as text (`punch train --grid 3,3,3`): three whole counts, each within the grid's bounds
    (a grid of 10^12 placements would otherwise be found out only after the first search, as a MemoryError)."""
    try:
        counts = [int(part) for part in text.split(",")]
    except ValueError:
        counts = []
    if len(counts) != 3:
        raise OptionError(f"{where} {text!r}: must be three whole numbers, distance,height,side")
    for count in counts:
        _check_number(where, count, int, limits, True)
