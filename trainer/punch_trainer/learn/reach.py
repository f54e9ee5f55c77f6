"""The reach volume: the target placements a policy covers (`punch_core::spec::ReachVolume`, announced in
the training server's handshake and written into every policy file as `punch_reach_volume`), and the
placements, bag motions and starting poses that training and evaluation draw from it.

Seeds: training draws from its `--seed` (search grid: fixed; A2C episodes: seed + 1; A2C's validation
placements: seed + 2). `punch eval` draws its held-out placements from `HELD_OUT_SEED` unless told otherwise,
a seed no training stage uses.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from punch_trainer.errors import PunchError
from punch_trainer.sim.conditions import EpisodeConditions

REACH_LIMIT_M = 3.0
"""No reach volume extends beyond this from the character (m): a human arm's reach is under 1 m."""
TARGET_SPEED_LIMIT_MPS = 10.0


class ReachError(PunchError, ValueError):
    """A reach volume (from a handshake, a dataset or a policy's metadata) that is malformed or of no sense."""
HELD_OUT_SEED = 2_147_483_647
"""the seed of `punch eval`'s placements (training seeds are small integers and their +1, +2)"""


@dataclass(frozen=True)
class ReachVolume:
    """A box of target centres in the character's frame (m): `distance_m` ahead, `height_m` above the
    ground, `side_m` to the character's left; the target's largest speed at the start (m/s); and whether a
    punch may start from any pose."""

    distance_m: tuple[float, float]
    height_m: tuple[float, float]
    side_m: tuple[float, float]
    max_target_speed_mps: float
    any_start_pose: bool

    def __post_init__(self) -> None:
        for name, (low, high), lowest in (("distance_m", self.distance_m, 0.0), ("height_m", self.height_m, 0.0),
                                          ("side_m", self.side_m, -REACH_LIMIT_M)):
            if not (math.isfinite(low) and math.isfinite(high) and lowest <= low <= high <= REACH_LIMIT_M):
                raise ReachError(f"reach volume {name} [{low}, {high}] is not a range from {lowest:g} to {REACH_LIMIT_M:g} m")
        if not 0.0 <= self.max_target_speed_mps <= TARGET_SPEED_LIMIT_MPS:  # NaN fails too
            raise ReachError(f"reach volume max_target_speed_mps {self.max_target_speed_mps} is not from 0 to "
                             f"{TARGET_SPEED_LIMIT_MPS:g} m/s")

    @classmethod
    def from_json(cls, value: dict[str, Any] | str) -> ReachVolume:
        """A reach volume from its JSON (text or parsed); ReachError for one malformed or out of bounds."""
        try:
            data = json.loads(value) if isinstance(value, str) else value

            def pair(key: str) -> tuple[float, float]:
                low, high = data[key]
                return round(float(low), 4), round(float(high), 4)  # the handshake's f32s

            any_start = data["any_start_pose"]
            if not isinstance(any_start, bool):
                raise ReachError(f"reach volume any_start_pose {any_start!r} is not true or false")
            return cls(pair("distance_m"), pair("height_m"), pair("side_m"), round(float(data["max_target_speed_mps"]), 4), any_start)
        except ReachError:
            raise
        except (KeyError, TypeError, ValueError, IndexError, OverflowError) as error:
            raise ReachError(f"malformed reach volume {str(value)[:200]!r}: {type(error).__name__}: {error}") from None

    @classmethod
    def spot(cls, bag: EpisodeConditions) -> ReachVolume:
        """A single placement, at rest, from the guard (the quickstart's reach)."""
        def at(value_m: float) -> tuple[float, float]:
            return round(float(value_m), 4), round(float(value_m), 4)

        return cls(at(bag.distance_m), at(bag.height_m), at(bag.side_m), 0.0, False)

    def moved_forward(self, metres: float) -> ReachVolume:
        """The same box `metres` further ahead (a lead hand's volume in the stance: ServerInfo.stance_lead_forward_m)."""
        low, high = self.distance_m
        return dataclasses.replace(self, distance_m=(round(low + metres, 4), round(high + metres, 4)))

    def to_json(self) -> str:
        return json.dumps({key: list(value) if isinstance(value, tuple) else value for key, value in asdict(self).items()},
                          sort_keys=True)

    @property
    def is_spot(self) -> bool:
        return all(low == high for low, high in (self.distance_m, self.height_m, self.side_m))

    def grid(self, counts: tuple[int, int, int] = (3, 3, 3)) -> list[EpisodeConditions]:
        """Placements at rest on a grid over the box: `counts` points along distance, height and side
        (ends included), the centre first (where a search warm-starts from)."""
        axes = [np.linspace(low, high, count) if count > 1 else np.array([(low + high) / 2])
                for (low, high), count in zip((self.distance_m, self.height_m, self.side_m), counts, strict=True)]
        points = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        centre = np.array([np.mean(self.distance_m), np.mean(self.height_m), np.mean(self.side_m)])
        points = points[np.argsort(np.linalg.norm((points - centre) / self.scale(), axis=1), kind="stable")]
        return [placement(*p) for p in points]

    def scale(self) -> np.ndarray:
        """Each axis's extent (1 where the box is flat), to measure distances between placements."""
        return np.array([max(high - low, 1e-6) for low, high in (self.distance_m, self.height_m, self.side_m)])

    def sample(self, rng: np.random.Generator, count: int, *, moving: float = 0.0) -> list[EpisodeConditions]:
        """`count` placements drawn uniformly from the box; a share `moving` of them with the bag swinging at
        a speed drawn uniformly up to the volume's largest, in a random horizontal direction."""
        low = np.array([self.distance_m[0], self.height_m[0], self.side_m[0]])
        high = np.array([self.distance_m[1], self.height_m[1], self.side_m[1]])
        points = rng.uniform(low, high, size=(count, 3))
        speeds = np.where(rng.uniform(size=count) < moving, rng.uniform(0, self.max_target_speed_mps, count), 0.0)
        angles = rng.uniform(0, 2 * np.pi, count)
        return [placement(*p, velocity_side_mps=s * np.sin(a), velocity_forward_mps=s * np.cos(a))
                for p, s, a in zip(points, speeds, angles, strict=True)]


def placement(distance_m: float, height_m: float, side_m: float, *, velocity_side_mps: float = 0.0,
              velocity_forward_mps: float = 0.0) -> EpisodeConditions:
    """A bag placement of plain floats (numpy's scalars become Python's, as the protocol writes them)."""
    return EpisodeConditions(float(distance_m), float(height_m), float(side_m), float(velocity_side_mps), float(velocity_forward_mps))


def nearest(points: list[EpisodeConditions], bag: EpisodeConditions, scale: np.ndarray) -> int:
    """Index of the placement in `points` nearest to `bag` (distances measured in units of `scale`)."""
    return int(np.argmin([np.linalg.norm((p.position_m() - bag.position_m()) / scale) for p in points]))
