"""What a policy file carries: the one list of its ONNX metadata entries' names, the typed record of them
(`PolicyMetadata`), the one reader (`read_policy_metadata`) and the metadata the one writer
(learn/export.py's `export_policy`, and learn/soup.py for a soup) puts in (`policy_entries`).

A policy file's metadata is the policy contract of the episodes it learned from, as the training server announced
it (punch_core/src/contract/spec.rs: `keys`, `PolicySpec::metadata`, `REQUIRED_METADATA`; the game reads it back
and refuses a file that lacks a required entry), plus the trainer's own entries (the reward, the motion style,
the trainer's version, a training summary), which no game reads. The names below mirror punch_core's `keys`
(tests/python/test_policy_file.py compares them with the Rust source and with a training server's reply). A
required entry that is missing raises `MissingMetadataError` naming it; an optional one is None when absent;
none gets a default."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from punch_trainer.errors import MissingMetadataError, PolicyFileError

if TYPE_CHECKING:
    import onnx

# --- the policy contract: punch_core::contract::spec::keys, in its order ------------------------------------
SPEC_VERSION = "punch_spec_version"
SPEC_HASH = "punch_spec_hash"
PHYSICS_HZ = "punch_physics_hz"
DECISION_PERIOD = "punch_decision_period"
FRAMES = "punch_frames"
SMOOTHING_WINDOW = "punch_smoothing_window"
OBSERVATION_SIZE = "punch_observation_size"
ACTION_SIZE = "punch_action_size"
ACTION_SPEC = "punch_action_spec"
REACH_VOLUME = "punch_reach_volume"
"""the target placements the policy covers (learn/reach.py `ReachVolume.to_json`); the game requires it"""
NOISE_SCALE = "punch_noise_scale"
"""optional: the share of a game's runtime noise sigma each degree of freedom gets (JSON list)"""
START_LOAD = "punch_start_load"
"""optional: the load the policy punches from (`hook`, `uppercut`: `punch train --load`); the game draws the arm there
first"""

CONTRACT_KEYS = (SPEC_VERSION, SPEC_HASH, PHYSICS_HZ, DECISION_PERIOD, FRAMES, SMOOTHING_WINDOW, OBSERVATION_SIZE,
                 ACTION_SIZE, ACTION_SPEC, REACH_VOLUME, NOISE_SCALE, START_LOAD)
"""every entry of punch_core's contract (`keys`)"""
ANNOUNCED_KEYS = (SPEC_VERSION, SPEC_HASH, PHYSICS_HZ, DECISION_PERIOD, FRAMES, SMOOTHING_WINDOW, OBSERVATION_SIZE,
                  ACTION_SIZE, ACTION_SPEC)
"""what a training server's `reset_done` announces as `policy_metadata` (`PolicySpec::metadata`); a dataset adds
`REACH_VOLUME` (learn/dataset.py), a style `NOISE_SCALE` (learn/export.py), a load `START_LOAD` (pipelines/train.py)"""
REQUIRED_METADATA = (SPEC_HASH, PHYSICS_HZ, DECISION_PERIOD, FRAMES, SMOOTHING_WINDOW)
"""the entries the game refuses to play a policy without (punch_core's `REQUIRED_METADATA`; `ReachVolume::from_metadata`
requires `REACH_VOLUME` too)"""

# --- the trainer's own entries (no game reads them) -----------------------------------------------------------
REWARD = "punch_reward"
"""the preset reward the policy was trained for (empty: trained for several, `punch pretrain`)"""
STYLE = "punch_style"
"""the motion style: `none`, NAME@WEIGHT, or a soup's ingredients' joined"""
TRAINER_VERSION = "punch_trainer_version"
TRAINING_SUMMARY = "punch_training_summary"
"""a JSON object: how the policy was made (the search's best return, a soup's ingredients, ...)"""
TRAINER_KEYS = (REWARD, STYLE, TRAINER_VERSION, TRAINING_SUMMARY)

REQUIRED_KEYS = (*REQUIRED_METADATA, REACH_VOLUME, OBSERVATION_SIZE, ACTION_SIZE)
"""what a policy file must carry for the trainer to read it: what the game requires, and the sizes of its
input and output (every file `export_policy` writes has them); every other entry is optional"""


@dataclass(frozen=True)
class PolicyMetadata:
    """A policy file's metadata, typed. Required entries are plain fields; optional ones are None when absent."""

    spec_hash: str
    physics_hz: int
    decision_period: int
    frames: int
    smoothing_window: int
    reach_volume: str
    """JSON text (learn/reach.py `ReachVolume.from_json` reads it)"""
    observation_size: int
    action_size: int
    spec_version: int | None
    action_spec: str | None
    noise_scale: str | None
    """JSON text, checked by the game"""
    reward: str | None
    """None when the file names none (or an empty one)"""
    style: str | None
    trainer_version: str | None
    training_summary: dict[str, Any] | None
    entries: dict[str, str]
    """every entry as the file holds it, in its order (what a soup compares and copies)"""

    @classmethod
    def from_entries(cls, entries: Mapping[str, str], source: str) -> PolicyMetadata:
        """The typed metadata of `entries` (a file's, named `source` in errors). Raises MissingMetadataError for
        a required entry missing, PolicyFileError for an entry that does not read as its type."""
        def required(key: str) -> str:
            if key not in entries:
                raise MissingMetadataError(f"{source}: its metadata has no {key} (a policy file of `punch train` "
                                           "or `punch pretrain` has it; export it again)", key)
            return entries[key]

        def whole(key: str, text: str) -> int:
            if not (text.isascii() and text.isdigit() and len(text) < 10):
                raise PolicyFileError(f"{source}: its metadata's {key} {text[:40]!r} is not a whole number", key)
            return int(text)

        optional = entries.get
        version = optional(SPEC_VERSION)
        reach = required(REACH_VOLUME)
        try:
            parsed = json.loads(reach)
        except ValueError as error:
            raise PolicyFileError(f"{source}: its metadata's {REACH_VOLUME} is not JSON ({error})", REACH_VOLUME) from None
        if not isinstance(parsed, dict):
            raise PolicyFileError(f"{source}: its metadata's {REACH_VOLUME} is not a JSON object", REACH_VOLUME)
        return cls(
            spec_hash=required(SPEC_HASH),
            physics_hz=whole(PHYSICS_HZ, required(PHYSICS_HZ)),
            decision_period=whole(DECISION_PERIOD, required(DECISION_PERIOD)),
            frames=whole(FRAMES, required(FRAMES)),
            smoothing_window=whole(SMOOTHING_WINDOW, required(SMOOTHING_WINDOW)),
            reach_volume=reach,
            observation_size=whole(OBSERVATION_SIZE, required(OBSERVATION_SIZE)),
            action_size=whole(ACTION_SIZE, required(ACTION_SIZE)),
            spec_version=None if version is None else whole(SPEC_VERSION, version),
            action_spec=optional(ACTION_SPEC),
            noise_scale=optional(NOISE_SCALE),
            reward=optional(REWARD) or None,
            style=optional(STYLE),
            trainer_version=optional(TRAINER_VERSION),
            training_summary=_summary(optional(TRAINING_SUMMARY), source),
            entries=dict(entries),
        )

    def contract(self) -> dict[str, str]:
        """The entries of punch_core's contract (`CONTRACT_KEYS`) the file holds, in its order."""
        return {key: value for key, value in self.entries.items() if key in CONTRACT_KEYS}


def _summary(text: str | None, source: str) -> dict[str, Any] | None:
    if text is None:
        return None

    def no_constant(name: str) -> float:
        raise ValueError(f"{name} is not a number")

    try:
        summary = json.loads(text, parse_constant=no_constant)
    except ValueError as error:
        raise PolicyFileError(f"{source}: its metadata's {TRAINING_SUMMARY} is not JSON ({error})", TRAINING_SUMMARY) from None
    if not isinstance(summary, dict):
        raise PolicyFileError(f"{source}: its metadata's {TRAINING_SUMMARY} is a {type(summary).__name__}, not an object",
                              TRAINING_SUMMARY)
    return summary


def model_entries(model: onnx.ModelProto) -> dict[str, str]:
    """Every metadata entry of a loaded ONNX model, in its order."""
    return {entry.key: entry.value for entry in model.metadata_props}


def read_entries(path: Path) -> dict[str, str]:
    """Every metadata entry of the ONNX file `path` (its weights are not read); PolicyFileError when it is missing
    or no ONNX model."""
    import onnx

    if not Path(path).is_file():
        raise PolicyFileError(f"policy file not found: {path}")
    try:
        model = onnx.load(str(path), load_external_data=False)
    except Exception as error:  # onnx raises several types for a corrupt file
        raise PolicyFileError(f"{path} is not an ONNX model: {error}") from error
    return model_entries(model)


def read_policy_metadata(path: Path) -> PolicyMetadata:
    """The typed metadata of the policy file `path`: the one reader of policy files."""
    return PolicyMetadata.from_entries(read_entries(path), str(path))


def policy_entries(contract: Mapping[str, str], *, reward: str, style: str, trainer_version: str,
                   summary: Mapping[str, Any], noise_scale: list[float] | None = None) -> dict[str, str]:
    """The metadata the trainer writes into a policy file: the `contract` (as the training server announced it
    for the episodes the policy learned from, with the dataset's reach volume; copied whole, in its order) and
    the trainer's entries. Raises MissingMetadataError when the contract lacks a required entry, PolicyFileError
    when one does not read as its type."""
    entries = {**contract, REWARD: reward, STYLE: style, TRAINER_VERSION: trainer_version,
               TRAINING_SUMMARY: json.dumps(dict(summary))}
    if noise_scale is not None:
        entries[NOISE_SCALE] = json.dumps(noise_scale)
    PolicyMetadata.from_entries({key: value for key, value in entries.items() if key != TRAINING_SUMMARY}, "the policy to write")
    return entries
