"""Run checkpoints that survive being killed at any moment.

A checkpoint is written to a temporary file in the run directory, flushed to disk, then renamed over the
previous one (a rename within one file system is atomic), so a run interrupted at any instant leaves either
the old checkpoint or the new one, never half of one. The file is a `torch.save` of plain values and
tensors, loaded back with `weights_only=True` (no arbitrary pickled code).

A run directory holds `config.json` from its first moment, so `--resume runs/NAME` knows the run's
arguments, and `checkpoint.pt` from its first completed iteration (search) or update (A2C).

Nothing in a run directory is trusted as it is. config.json's values are checked against the options' bounds
(`punch_trainer/options.py`) and it holds a random `run_id`, kept for the run's life. A checkpoint file
starts with the SHA-256 of its contents (an edited or damaged file is refused) and records whose it is: the
run_id, seed, reward and reward fingerprint of the config.json that governs it (its folder's, else the folder
above); `load_checkpoint` refuses one that is not this run's, naming what differs. The
pipelines check each restored value's type, range and finiteness (`number`, `array`) and turn anything else
that does not fit into a CheckpointError, so a tampered file ends as one `punch:` line.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import secrets
import time
from dataclasses import asdict, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import torch

from punch_trainer.errors import PunchError
from punch_trainer.options import OptionError, check_options

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

CHECKPOINT_FILE = "checkpoint.pt"
CONFIG_FILE = "config.json"
CHECKPOINT_VERSION = 2
_MAGIC = b"punch checkpoint v2 sha256 "
_MAX_CONFIG_BYTES = 1 << 20

ArgsT = TypeVar("ArgsT", bound="DataclassInstance")


class CheckpointError(PunchError):
    """A run directory cannot be resumed: no checkpoint or config, or one that is unreadable or of another run."""


def default_run_dir(name: str, seed: int) -> Path:
    """runs/<name>__<seed>__<unix time>, with a reward file's path made into a plain folder name."""
    for character in "/:":
        name = name.replace(character, "_")
    return Path("runs") / f"{name.removesuffix('.py')}__{seed}__{int(time.time())}"


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Writes `data` to `path` so that readers see the old file or the new one, whole."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(temporary, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:  # Ctrl-C included: leave no half-written temporary file behind
        temporary.unlink(missing_ok=True)
        raise


def save_checkpoint(run_dir: Path, kind: str, state: dict[str, Any]) -> None:
    """Saves `state` (tensors, numpy arrays, numbers, strings, lists and dicts of them) as the run's checkpoint,
    with the identity of the run it belongs to and a checksum of it all."""
    buffer = io.BytesIO()
    torch.save({"version": CHECKPOINT_VERSION, "kind": kind, "identity": run_identity(run_dir), "state": _to_torch(state)}, buffer)
    body = buffer.getvalue()
    atomic_write_bytes(run_dir / CHECKPOINT_FILE, _MAGIC + hashlib.sha256(body).hexdigest().encode() + b"\n" + body)


def load_checkpoint(run_dir: Path, kind: str) -> dict[str, Any] | None:
    """The run's checkpoint state, or None if the run has none yet. Numpy arrays come back as tensors.
    CheckpointError for a file that is damaged, edited, of another kind, or of another run."""
    path = run_dir / CHECKPOINT_FILE
    if not path.exists():
        return None
    saved = read_checkpoint(path, kind)
    expected = run_identity(run_dir)
    for key, label in (("seed", "seed"), ("reward", "reward"), ("reward_fingerprint", "reward's source"), ("run_id", "run")):
        if saved["identity"].get(key) != expected.get(key):
            raise CheckpointError(f"{path} is not this run's checkpoint: its {label} differs from the run's "
                                  f"({saved['identity'].get(key)!r}, not {expected.get(key)!r}); it is not resumed")
    state: dict[str, Any] = saved["state"]
    return state


def read_checkpoint(path: Path, kind: str) -> dict[str, Any]:
    """A checkpoint file of `kind`, whichever run wrote it: its `identity` and `state`. CheckpointError for a file
    that is missing, damaged, edited or of another kind."""
    try:
        data = path.read_bytes()
    except OSError as error:
        raise CheckpointError(f"cannot read the checkpoint {path}: {error}") from error
    header, _, body = data.partition(b"\n")
    if not header.startswith(_MAGIC):
        raise CheckpointError(f"{path} is not a version-{CHECKPOINT_VERSION} punch checkpoint (an older punch's, or "
                              "not a checkpoint); it cannot be resumed: start the run again")
    if header.removeprefix(_MAGIC) != hashlib.sha256(body).hexdigest().encode():
        raise CheckpointError(f"{path} does not match its checksum: it was edited or damaged, and is not resumed")
    try:
        saved = torch.load(io.BytesIO(body), weights_only=True)
    except Exception as error:  # torch raises many types for a damaged file
        raise CheckpointError(f"cannot read the checkpoint {path}: {error}") from error
    if (not isinstance(saved, dict) or saved.get("version") != CHECKPOINT_VERSION or saved.get("kind") != kind
            or not isinstance(saved.get("state"), dict) or not isinstance(saved.get("identity"), dict)):
        raise CheckpointError(f"{path} is not a version-{CHECKPOINT_VERSION} {kind} checkpoint")
    return saved


def _governing_config(run_dir: Path) -> Path | None:
    """The config.json a run folder's checkpoint belongs to: its own, else its parent's (a `punch train` stage)."""
    for folder in (run_dir, run_dir.parent):
        if (folder / CONFIG_FILE).is_file():
            return folder / CONFIG_FILE
    return None


def _read_config_dict(path: Path) -> dict[str, Any]:
    try:
        if path.stat().st_size > _MAX_CONFIG_BYTES:
            raise CheckpointError(f"{path} is larger than {_MAX_CONFIG_BYTES} bytes: not a run's config")
        config = json.loads(path.read_text(), parse_constant=_refuse_constant)
    except (OSError, ValueError) as error:
        raise CheckpointError(f"{path.parent} is not a resumable run directory: cannot read {path} ({error})") from error
    if not isinstance(config, dict):
        raise CheckpointError(f"{path} holds a {type(config).__name__}, not a run's config")
    return config


def _refuse_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number a run's config may hold")


def run_identity(run_dir: Path) -> dict[str, Any]:
    """Whose a checkpoint in `run_dir` is: the governing config.json's run_id, seed, reward and reward
    fingerprint (its other values are checked as options when a resume reads them)."""
    path = _governing_config(run_dir)
    if path is None:
        return {}
    config = _read_config_dict(path)
    return {key: config.get(key) for key in ("run_id", "seed", "reward", "reward_fingerprint")}


def write_config(run_dir: Path, args: Any, **extra: Any) -> None:
    """Writes the run's arguments (a dataclass) and `extra` facts to config.json, atomically, keeping the
    run_id (and reward_fingerprint, unless given) of the config already there, or drawing a new run_id."""
    config = {k: (str(v) if isinstance(v, Path) else [str(p) if isinstance(p, Path) else p for p in v] if isinstance(v, list) else v)
              for k, v in asdict(args).items()}
    config.update(extra)
    path = run_dir / CONFIG_FILE
    previous = _read_config_dict(path) if path.is_file() else {}
    if "reward_fingerprint" in previous and "reward_fingerprint" not in config:
        config["reward_fingerprint"] = previous["reward_fingerprint"]
    run_id = previous.get("run_id")
    config["run_id"] = run_id if isinstance(run_id, str) and len(run_id) == 32 else secrets.token_hex(16)
    atomic_write_bytes(path, (json.dumps(config, indent=2) + "\n").encode())


def read_config(run_dir: Path, args_type: type[ArgsT]) -> ArgsT:
    """The arguments a run was started with, from its config.json, with `out` set to the run directory; every
    value checked as a command-line option would be (CheckpointError naming it)."""
    path = run_dir / CONFIG_FILE
    config = _read_config_dict(path)
    known = {f.name: f for f in fields(args_type)}
    values = {k: v for k, v in config.items() if k in known and k != "out"}
    values["out"] = run_dir
    try:
        args = args_type(**values)
        check_options(args, source=str(path))
    except OptionError as error:
        raise CheckpointError(str(error)) from None
    except TypeError as error:  # a required field missing
        raise CheckpointError(f"{path} is not a run's config: {error}") from None
    return args


def stored_config(run_dir: Path) -> dict[str, Any]:
    """The facts config.json holds beside the arguments (the reward's fingerprint, frames): read, not trusted."""
    return _read_config_dict(run_dir / CONFIG_FILE)


def number(state: dict[str, Any], key: str, low: float, high: float, *, integer: bool = False) -> Any:
    """`state[key]`, refused unless it is a finite number (a whole one when `integer`) in [low, high]."""
    value: Any = state.get(key)
    if isinstance(value, torch.Tensor) and value.numel() == 1:
        value = value.item()
    kind_ok = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not kind_ok or not math.isfinite(value) or not low <= value <= high:
        raise CheckpointError(f"the checkpoint's {key} is {value!r}; it must be a finite "
                              f"{'whole ' if integer else ''}number from {low:g} to {high:g}")
    return value


def flag(state: dict[str, Any], key: str) -> bool:
    """`state[key]`, refused unless it is true or false."""
    value = state.get(key)
    if not isinstance(value, bool):
        raise CheckpointError(f"the checkpoint's {key} is {value!r}; it must be true or false")
    return value


def array(state: dict[str, Any], key: str, shape: tuple[int, ...], low: float = -math.inf, high: float = math.inf) -> np.ndarray:
    """`state[key]` as a float numpy array of `shape`, refused unless every value is finite and in [low, high]."""
    value = state.get(key)
    if isinstance(value, torch.Tensor):
        value = value.numpy()
    if not isinstance(value, np.ndarray) or value.dtype.kind != "f" or value.shape != shape:
        described = f"{value.dtype} {value.shape}" if isinstance(value, np.ndarray) else type(value).__name__
        raise CheckpointError(f"the checkpoint's {key} is {described}; it must be floats of shape {shape}")
    if not np.all(np.isfinite(value)) or (value.size and (value.min() < low or value.max() > high)):
        raise CheckpointError(f"the checkpoint's {key} holds values that are not finite or outside [{low:g}, {high:g}]")
    return value


def _to_torch(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return torch.from_numpy(np.ascontiguousarray(value))
    if isinstance(value, dict):
        return {k: _to_torch(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_to_torch(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value

