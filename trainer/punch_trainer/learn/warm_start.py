"""Warm start (`punch train --init-from RUN`): A2C starts from an earlier run's best policy (or one of its
snapshots, RUN/a2c/snapshots/update_<N>, or an exported policy file such as the addon's own
addons/punch_controller/policies/hook.onnx) instead of from a pretraining on this run's search: to train a policy
further, and when the observation has only gained entries since (a policy contract that added inputs, such as
version 3's arm lengths). Every input the earlier policy had keeps its weights and its
normalisation; every new one gets zero weights, so the policy first acts exactly as the earlier one did, and the
normalisation of this run's episodes, so A2C can learn what the new input says. A policy file holds the actor
alone: the critic then keeps this run's fresh weights, and the caller fits it (`pretrain.fit_critic`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import torch
from google.protobuf.message import DecodeError  # type: ignore[import-untyped]  # protobuf ships no stubs here
from onnx import numpy_helper

from punch_trainer.errors import PolicyFileError, PunchError
from punch_trainer.learn.checkpoint import CHECKPOINT_FILE, CheckpointError, read_checkpoint
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.policy_file import PolicyMetadata, model_entries

SNAPSHOT_KIND = "a2c_snapshot"
"""the checkpoint kind of a snapshot of A2C's model (`punch train --a2c-snapshot-every`)"""
INPUT_LAYERS = ("actor.0.weight", "critic.0.weight")
"""the first layers of the actor and the critic: the only weights that see the observation"""


class WarmStartError(PunchError):
    """An earlier run that a warm start cannot use: no A2C checkpoint, another network, or inputs this run lacks."""


def check_source(source: Path) -> None:
    """Refuses `--init-from source` before the search's minutes are spent when nothing there can be started from:
    a policy file that is not there, or a folder that is neither a finished run (RUN/a2c/checkpoint.pt) nor one of
    its snapshots. What the file or checkpoint holds is read, and checked, when A2C starts (`warm_start`)."""
    if source.suffix == ".onnx":
        if not source.is_file():
            raise WarmStartError(f"cannot start from {source}: no such policy file")
        return
    is_snapshot = (source / CHECKPOINT_FILE).is_file() and source.parent.name == "snapshots"
    if not is_snapshot and not (source / "a2c" / CHECKPOINT_FILE).is_file():
        raise WarmStartError(f"cannot start from {source}: it is neither a finished `punch train` run (no "
                             f"{source / 'a2c' / CHECKPOINT_FILE}) nor a snapshot (RUN/a2c/snapshots/update_<N>); a "
                             "recipe's run keeps each stage's run in its own folder (DIR/<stage>)")


def earlier_observation_names(run_dir: Path) -> list[str]:
    """The observation names of the earlier run `run_dir` (its search's dataset records them)."""
    dataset = run_dir / "search" / "dataset.npz"
    try:
        with np.load(dataset, allow_pickle=False) as data:
            return [str(name) for name in data["observation_names"]]
    except (OSError, KeyError, ValueError) as error:
        raise WarmStartError(f"{run_dir} is not a finished `punch train` run: cannot read the observation names "
                             f"of {dataset} ({error})") from None


def earlier_parameters(source: Path) -> tuple[dict[str, torch.Tensor], Path]:
    """The parameters `--init-from source` names and the run they come from: a run folder's best A2C policy, or a
    snapshot folder's (RUN/a2c/snapshots/update_<N>) model."""
    is_snapshot = (source / CHECKPOINT_FILE).is_file() and source.parent.name == "snapshots"
    try:
        if is_snapshot:
            return read_checkpoint(source / CHECKPOINT_FILE, SNAPSHOT_KIND)["state"]["model"], source.parents[2]
        return read_checkpoint(source / "a2c" / CHECKPOINT_FILE, "a2c")["state"]["best_model"], source
    except (CheckpointError, KeyError) as error:
        raise WarmStartError(f"cannot start from {source}: {error}") from None


def policy_file_parameters(path: Path, names: list[str], spec_hash: str) -> dict[str, torch.Tensor]:
    """The actor's parameters in an exported policy file (learn/export.py names them `model.<parameter>`), whose
    observation must be this run's: the same spec (its `punch_spec_hash`) and so the same `names`."""
    try:
        policy = onnx.load(str(path))
    except (OSError, ValueError, DecodeError) as error:
        raise WarmStartError(f"cannot start from {path}: not a readable policy file ({error})") from None
    try:
        metadata = PolicyMetadata.from_entries(model_entries(policy), str(path))
    except PolicyFileError as error:
        raise WarmStartError(f"cannot start from {path}: {error}") from None
    if metadata.spec_hash != spec_hash or metadata.observation_size != len(names):
        raise WarmStartError(f"cannot start from {path}: its observation spec ({metadata.spec_hash}, "
                             f"{metadata.observation_size} inputs) is not this run's ({spec_hash}, {len(names)} inputs)")
    return actor_parameters(policy)


def actor_parameters(policy: onnx.ModelProto) -> dict[str, torch.Tensor]:
    """The actor's parameters in a loaded policy file, by their names in `ActorCritic` (learn/export.py names
    them `model.<parameter>`)."""
    prefix = "model."
    parameters = {tensor.name.removeprefix(prefix): torch.as_tensor(numpy_helper.to_array(tensor).copy())
                  for tensor in policy.graph.initializer if tensor.name.startswith(prefix)}
    # The exporter leaves out a bias of zeros (its layer then has no bias input).
    for weight in [key for key in parameters if key.endswith(".weight")]:
        bias = weight.removesuffix(".weight") + ".bias"
        parameters.setdefault(bias, torch.zeros(parameters[weight].shape[0]))
    return parameters


def warm_start(model: ActorCritic, source: Path, names: list[str], statistics: np.ndarray, spec_hash: str) -> list[str]:
    """Loads the policy `source` names (a run's best, a snapshot: `earlier_parameters`, or a policy file:
    `policy_file_parameters`) into `model`, whose observation is `names` (spec `spec_hash`); `statistics`
    [n, len(names)] are observations of this run's episodes, for the new inputs' normalisation. Returns the
    names of the new inputs."""
    if source.suffix == ".onnx":
        earlier = policy_file_parameters(source, names, spec_hash)
        earlier_names = names
        # The file holds no critic: it keeps this run's fresh weights, to be fitted by the caller.
        earlier.update({key: value for key, value in model.state_dict().items() if key.startswith("critic.")})
    else:
        earlier, run_dir = earlier_parameters(source)
        earlier_names = earlier_observation_names(run_dir)
    lost = [name for name in earlier_names if name not in names]
    if lost:
        raise WarmStartError(f"cannot start from {source}: its policy observes {', '.join(lost)}, which this run's "
                             "observation has not")
    columns = torch.as_tensor([names.index(name) for name in earlier_names])
    state = model.state_dict()
    earlier_shapes = {"obs_mean": (len(earlier_names),), "obs_std": (len(earlier_names),),
                      **{key: (state[key].shape[0], len(earlier_names)) for key in INPUT_LAYERS}}
    for key, value in state.items():
        old = earlier.get(key)
        expected = earlier_shapes.get(key, tuple(value.shape))
        if old is None or tuple(old.shape) != expected:
            raise WarmStartError(f"cannot start from {source}: its network differs from this run's at '{key}' "
                                 f"({None if old is None else tuple(old.shape)}, expected {expected})")
    mean = torch.as_tensor(statistics.mean(axis=0), dtype=torch.float32)
    std = torch.as_tensor(statistics.std(axis=0) + 1e-3, dtype=torch.float32)  # as ActorCritic.set_normalization
    mean[columns], std[columns] = earlier["obs_mean"], earlier["obs_std"]
    started = {key: earlier[key].clone() for key in state if key not in (*INPUT_LAYERS, "obs_mean", "obs_std")}
    started["obs_mean"], started["obs_std"] = mean, std
    for key in INPUT_LAYERS:
        weights = torch.zeros_like(state[key])
        weights[:, columns] = earlier[key]
        started[key] = weights
    model.load_state_dict(started)
    return [name for name in names if name not in earlier_names]
