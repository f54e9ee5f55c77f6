"""The mirror of the character's world across its sagittal plane (left and right swapped), as the training server
announces it in its handshake (`mirror`): punch_core::contract::mirror defines every rule, once; this only applies
its tables. Entry i of a mirrored vector is `sign[i] * value[partner[i]]`, for features, observations and actions
alike; a mirrored episode's conditions change the sign of the fields the table says (the bag's side and sideways
velocity, the body's sideways walk and its turning). Mirroring twice gives back the input exactly. docs/env.md,
"Mirror", lists the rules."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from punch_trainer.sim.conditions import EpisodeConditions


@dataclass(frozen=True)
class VectorMirror:
    """The mirror of one kind of vector: where each entry comes from, and its sign."""

    partner: np.ndarray
    sign: np.ndarray

    @classmethod
    def from_wire(cls, value: Mapping[str, Any]) -> VectorMirror:
        partner, sign = np.asarray(value["partner"], np.int64), np.asarray(value["sign"], np.float64)
        if partner.shape != sign.shape or not np.array_equal(partner[partner], np.arange(partner.size)):
            raise ValueError("a mirror table must pair every entry with one partner whose partner it is")
        return cls(partner, sign)

    def __call__(self, values: np.ndarray) -> np.ndarray:
        """`values` [..., N] mirrored along its last axis (the dtype kept)."""
        values = np.asarray(values)
        mirrored: np.ndarray = values[..., self.partner] * self.sign.astype(values.dtype)
        return mirrored


@dataclass(frozen=True)
class MirrorRules:
    """The handshake's `mirror`: tables for the per-frame features, the observation, the action (and any
    per-DOF vector), and the sign of each episode-condition field."""

    features: VectorMirror
    observations: VectorMirror
    actions: VectorMirror
    condition_signs: dict[str, float]

    @classmethod
    def from_wire(cls, value: Mapping[str, Any]) -> MirrorRules:
        return cls(VectorMirror.from_wire(value["features"]), VectorMirror.from_wire(value["observation"]),
                   VectorMirror.from_wire(value["action"]), {str(k): float(v) for k, v in value["conditions"].items()})

    def conditions(self, conditions: EpisodeConditions) -> EpisodeConditions:
        """The conditions of the mirrored episode; a field the table does not name is an error."""
        wire = conditions.to_wire()
        unknown = set(wire) - set(self.condition_signs)
        if unknown:
            raise ValueError(f"the training server's mirror has no rule for {sorted(unknown)}")
        return EpisodeConditions.from_wire({name: (-value if self.condition_signs[name] < 0 else value)
                                            for name, value in wire.items()})
