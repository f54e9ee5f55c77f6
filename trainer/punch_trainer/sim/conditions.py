"""Typed records of how an episode starts. `EpisodeConditions`, one character's (punch_core's struct of the same
name): where the bag hangs and how it moves, how the character itself moves, and the sizes of its arms.
`EpisodeStart`, a reset's options for every character: their conditions and the actions each plays before its
episode. The wire writes a character's conditions as a JSON object, a reset's `bags` entry (docs/protocol.md,
`reset`: the wire's names are unchanged); these are the trainer's side of it. learn/volume.py's
`ConditionSampler` draws them for A2C."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from punch_trainer.scene import SCENE_ARM_LENGTHS_M as SCENE_ARM_LENGTHS_M
from punch_trainer.scene import SCENE_BAG_RADIUS_M as SCENE_BAG_RADIUS_M


@dataclass(frozen=True)
class EpisodeConditions:
    """One character's conditions at the start of an episode: the bag's centre in the character's frame and its
    velocity, the character's own motion and its arm sizes (the fields' defaults: still, the scene's arms)."""

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
    bag_glides: bool = False
    """the bag's rope is carried at the bag's velocity (a target walking), instead of the bag swinging"""
    bag_rides: bool = False
    """the bag's rope is carried with the character's root (both moved as one: it stays where it is relative
    to the character however the body walks, turns, lunges or bobs)"""
    body_side_mps: float = 0.0
    """the character's own walking velocity toward its left, as it turns (punch_core::motion)"""
    body_forward_mps: float = 0.0
    """the character's own walking velocity ahead"""
    body_turn_rad_s: float = 0.0
    """the character's turning rate, positive to its left"""
    body_lunge_m: float = 0.0
    """a step-in of this length over the punch's first 0.25 s"""
    body_bob_m: float = 0.0
    """the vertical bob of walking, amplitude at 2 Hz"""
    arms_upper_arm_scale: float = 1.0
    """the character's upper arms, times the scene's (punch_core::arm_size, as `PunchCharacter.size_arms`)"""
    arms_forearm_scale: float = 1.0
    """its forearms (elbow to fist centre), times the scene's"""
    arms_shoulder_shift_m: float = 0.0
    """how far each shoulder sits further out than the scene's (negative: in)"""

    @classmethod
    def from_wire(cls, value: Mapping[str, float | bool]) -> EpisodeConditions:
        """From the protocol's JSON object (the handshake's `default_bag`, a dataset's `bag`)."""
        converted: dict[str, Any] = {field.name: (bool if field.type == "bool" else float)(value[field.name])
                                     for field in fields(cls) if field.name in value}
        return cls(**converted)

    def to_wire(self) -> dict[str, float | bool]:
        """The protocol's JSON object."""
        return asdict(self)

    def body_moves(self) -> bool:
        """Whether the character's root moves through the episode."""
        return any(getattr(self, name) != 0.0 for name in BODY_MOTION_FIELDS)

    def position_m(self) -> np.ndarray:
        """(distance, height, side)."""
        return np.array([self.distance_m, self.height_m, self.side_m])

    def over(self, changes: Mapping[str, float | bool]) -> EpisodeConditions:
        """This placement with some of its values replaced (a user's partial placement over the default)."""
        return EpisodeConditions.from_wire({**self.to_wire(), **changes})


ARM_SCALE_RANGE = (0.75, 1.25)
"""the arms (shoulder to fist centre) a placement's `arms_*` and `PunchCharacter.size_arms` accept, as fractions of
the scene's (punch_core::arm_size::ARM_SCALE_RANGE)"""
SEGMENT_SCALE_RANGE = (0.65, 1.35)
"""each of the two lengths they accept, as fractions of the scene's (punch_core::arm_size::SEGMENT_SCALE_RANGE)"""
UPPER_ARM_SHARE = SCENE_ARM_LENGTHS_M[0] / (SCENE_ARM_LENGTHS_M[0] + SCENE_ARM_LENGTHS_M[1])
"""the scene's upper arm's share of its arm: an arm's scale from its segments' scales"""


def arm_scale(upper_arm_scale: float, forearm_scale: float) -> float:
    """The arm's (shoulder to fist centre) scale when its upper arm and forearm are scaled so."""
    return UPPER_ARM_SHARE * upper_arm_scale + (1 - UPPER_ARM_SHARE) * forearm_scale


BODY_MOTION_FIELDS = ("body_side_mps", "body_forward_mps", "body_turn_rad_s", "body_lunge_m", "body_bob_m")
"""the placement's fields that move the character's root"""


@dataclass(frozen=True)
class EpisodeStart:
    """The start of one episode for every character: what `PunchVectorEnv.reset` takes as `options`."""

    bags: list[EpisodeConditions]
    """one placement per character"""
    lead_in: np.ndarray | None = None
    """raw actions [characters, decisions, A] each character plays before its episode (docs/protocol.md, `reset`)"""
