"""Typed records of how an episode starts: where the bag hangs and how it moves (`BagPlacement`), and a reset's
options for every character (`EpisodeStart`). The wire writes a placement as a JSON object
(docs/protocol.md, `reset`); these are the trainer's side of it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields

import numpy as np


@dataclass(frozen=True)
class BagPlacement:
    """The bag's centre in the character's frame and its velocity at the start of an episode."""

    distance_m: float
    """ahead of the character"""
    height_m: float
    """above the ground"""
    side_m: float
    """to the character's left"""
    velocity_side_mps: float = 0.0
    """toward the character's left (a velocity sets the bag swinging on its rope)"""
    velocity_forward_mps: float = 0.0
    """away from the character"""

    @classmethod
    def from_wire(cls, value: Mapping[str, float]) -> BagPlacement:
        """From the protocol's JSON object (the handshake's `default_bag`, a dataset's `bag`)."""
        return cls(**{field.name: float(value[field.name]) for field in fields(cls) if field.name in value})

    def to_wire(self) -> dict[str, float]:
        """The protocol's JSON object."""
        return asdict(self)

    def position_m(self) -> np.ndarray:
        """(distance, height, side)."""
        return np.array([self.distance_m, self.height_m, self.side_m])

    def over(self, changes: Mapping[str, float]) -> BagPlacement:
        """This placement with some of its values replaced (a user's partial placement over the default)."""
        return BagPlacement.from_wire({**self.to_wire(), **changes})


@dataclass(frozen=True)
class EpisodeStart:
    """The start of one episode for every character: what `PunchVectorEnv.reset` takes as `options`."""

    bags: list[BagPlacement]
    """one placement per character"""
    lead_in: np.ndarray | None = None
    """raw actions [characters, decisions, A] each character plays before its episode (docs/protocol.md, `reset`)"""
