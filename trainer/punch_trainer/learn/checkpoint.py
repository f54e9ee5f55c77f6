"""Run checkpoints that survive being killed at any moment.

A checkpoint is written to a temporary file in the run directory, flushed to disk, then renamed over the
previous one (a rename within one file system is atomic), so a run interrupted at any instant leaves either
the old checkpoint or the new one, never half of one. The file is a `torch.save` of plain values and
tensors, loaded back with `weights_only=True` (no arbitrary pickled code).

A run directory holds `config.json` from its first moment, so `--resume runs/NAME` knows the run's
arguments, and `checkpoint.pt` from its first completed iteration (search) or update (A2C).
"""

from __future__ import annotations

import io
import json
import os
import time
from dataclasses import asdict, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import torch

from punch_trainer.errors import PunchError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

CHECKPOINT_FILE = "checkpoint.pt"
CONFIG_FILE = "config.json"
CHECKPOINT_VERSION = 1

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
    """Saves `state` (tensors, numpy arrays, numbers, strings, lists and dicts of them) as the run's checkpoint."""
    buffer = io.BytesIO()
    torch.save({"version": CHECKPOINT_VERSION, "kind": kind, "state": _to_torch(state)}, buffer)
    atomic_write_bytes(run_dir / CHECKPOINT_FILE, buffer.getvalue())


def load_checkpoint(run_dir: Path, kind: str) -> dict[str, Any] | None:
    """The run's checkpoint state, or None if the run has none yet. Numpy arrays come back as tensors."""
    path = run_dir / CHECKPOINT_FILE
    if not path.exists():
        return None
    try:
        saved = torch.load(path, weights_only=True)
    except Exception as error:  # torch raises many types for a damaged file
        raise CheckpointError(f"cannot read the checkpoint {path}: {error}") from error
    if not isinstance(saved, dict) or saved.get("version") != CHECKPOINT_VERSION or saved.get("kind") != kind:
        raise CheckpointError(f"{path} is not a version-{CHECKPOINT_VERSION} {kind} checkpoint")
    state: dict[str, Any] = saved["state"]
    return state


def write_config(run_dir: Path, args: Any, **extra: Any) -> None:
    """Writes the run's arguments (a dataclass) and `extra` facts to config.json, atomically."""
    config = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(args).items()}
    config.update(extra)
    atomic_write_bytes(run_dir / CONFIG_FILE, (json.dumps(config, indent=2) + "\n").encode())


def read_config(run_dir: Path, args_type: type[ArgsT]) -> ArgsT:
    """The arguments a run was started with, from its config.json, with `out` set to the run directory."""
    path = run_dir / CONFIG_FILE
    try:
        config = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise CheckpointError(f"{run_dir} is not a resumable run directory: cannot read {path} ({error})") from error
    known = {f.name: f for f in fields(args_type)}
    values = {k: v for k, v in config.items() if k in known}
    values["out"] = run_dir
    return args_type(**values)


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

