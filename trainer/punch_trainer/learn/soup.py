"""`punch soup`: one policy whose weights are the mean of several policies of one lineage, a weight-space
ensemble (Wortsman et al. 2022, "Model soups", and "Robust fine-tuning of zero-shot models", WiSE-FT). Each round
of A2C from one policy file trades something for what it gains (experiments/notebook.md); policies fine-tuned from
one parent stay close enough in weight space that their mean can keep what each gained.

The mean is only meaningful among policies of one lineage, so every ingredient must share the network, the
observation normalisation (fine-tuning keeps the parent's) and every metadata entry but the three that tell
how each was trained (`KEPT_APART`). Anything else is refused with a `SoupError`. The soup records its
ingredients (file, SHA-256, style, training summary) in its `punch_training_summary`."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import onnx
import torch
from google.protobuf.message import DecodeError  # type: ignore[import-untyped]  # protobuf ships no stubs here

from punch_trainer import __version__
from punch_trainer.errors import PolicyFileError, PunchError
from punch_trainer.learn.export import export_onnx
from punch_trainer.learn.policy import Actor, ActorCritic
from punch_trainer.learn.warm_start import actor_parameters
from punch_trainer.policy_file import STYLE, TRAINER_VERSION, TRAINING_SUMMARY, PolicyMetadata, model_entries

KEPT_APART = (STYLE, TRAINER_VERSION, TRAINING_SUMMARY)
"""metadata that may differ between ingredients (how each was trained); every other entry (the policy
contract, the reward, the noise scale) must be equal"""
NORMALISATION = ("obs_mean", "obs_std")
STYLE_SEPARATOR = " + "
"""joins the ingredients' distinct `punch_style`s in the soup's"""


class SoupError(PunchError):
    """Policies that cannot be averaged: an unreadable file, too few, or not of one lineage."""


@dataclass(frozen=True)
class Ingredient:
    """One policy file of a soup, as read."""

    path: Path
    metadata: PolicyMetadata
    parameters: dict[str, torch.Tensor]
    sha256: str


def read_ingredient(path: Path) -> Ingredient:
    """A policy file's metadata, actor parameters and SHA-256."""
    try:
        content = Path(path).read_bytes()
        policy = onnx.load_from_string(content)
    except (OSError, ValueError, DecodeError) as error:
        raise SoupError(f"{path}: not a readable policy file ({error})") from None
    try:
        metadata = PolicyMetadata.from_entries(model_entries(policy), str(path))
    except PolicyFileError as error:
        raise SoupError(f"{error}, so it is no policy file of `punch train`") from None
    parameters = actor_parameters(policy)
    if not parameters:
        raise SoupError(f"{path}: it holds no actor parameters (model.*)")
    broken = sorted(key for key, value in parameters.items() if not torch.isfinite(value).all())
    if broken:
        raise SoupError(f"{path}: its weights {', '.join(broken)} are not all finite numbers")
    return Ingredient(Path(path), metadata, parameters, hashlib.sha256(content).hexdigest())


def check_one_lineage(first: Ingredient, other: Ingredient) -> None:
    """Raises SoupError unless `other` can be averaged with `first`."""
    mine, theirs = first.metadata.entries, other.metadata.entries
    differing = sorted(key for key in mine.keys() | theirs.keys() if key not in KEPT_APART and mine.get(key) != theirs.get(key))
    if differing:
        raise SoupError(f"{other.path} differs from {first.path} in {', '.join(differing)}: a soup averages policies "
                        "of one contract, reward and noise scale")
    shapes = {key: tuple(value.shape) for key, value in first.parameters.items()}
    if shapes != {key: tuple(value.shape) for key, value in other.parameters.items()}:
        raise SoupError(f"{other.path} has another network than {first.path}")
    for key in NORMALISATION:
        if key in shapes and not torch.equal(first.parameters[key], other.parameters[key]):
            raise SoupError(f"{other.path} normalises its observation otherwise than {first.path} ({key}): they are "
                            "not fine-tuned from one parent, and the mean of their weights means nothing")


def style_of(ingredient: Ingredient) -> str:
    """An ingredient's motion style (`none` for a file that names none: one trained before styles were)."""
    return ingredient.metadata.style or "none"


def soup(paths: list[Path], out: Path) -> Path:
    """Writes to `out` the policy whose every actor parameter is the mean of the `paths` policies' (at least
    two, of one lineage). Its metadata is theirs, with the ingredients' styles joined by STYLE_SEPARATOR and a
    training summary listing them; the export is verified against onnxruntime as `punch train`'s are."""
    if len(paths) < 2:
        raise SoupError(f"a soup needs at least two policies, got {len(paths)}")
    ingredients = [read_ingredient(path) for path in paths]
    first = ingredients[0]
    for other in ingredients[1:]:
        check_one_lineage(first, other)
    mean = {key: torch.stack([ingredient.parameters[key] for ingredient in ingredients]).mean(dim=0)
            for key in first.parameters}
    observation_size, action_size = first.metadata.observation_size, first.metadata.action_size
    model = ActorCritic(observation_size, action_size, hidden=int(mean["actor.0.weight"].shape[0]))
    state = model.state_dict()  # the critic keeps fresh weights: a policy file holds none
    unknown = sorted(mean.keys() - state.keys())
    if unknown or any(tuple(mean[key].shape) != tuple(state[key].shape) for key in mean):
        raise SoupError(f"{first.path}: its network is not this trainer's ActorCritic ({', '.join(unknown) or 'shapes'})")
    model.load_state_dict({**state, **mean})
    styles = list(dict.fromkeys(style_of(ingredient) for ingredient in ingredients))
    first_summary = first.metadata.training_summary or {}
    summary: dict[str, Any] = {key: first_summary[key] for key in ("search_best_return", "reach") if key in first_summary}
    summary["soup"] = [{"file": str(ingredient.path), "sha256": ingredient.sha256, "style": style_of(ingredient),
                        "summary": ingredient.metadata.training_summary or {}} for ingredient in ingredients]
    metadata = {**first.metadata.entries, STYLE: STYLE_SEPARATOR.join(styles), TRAINER_VERSION: __version__,
                TRAINING_SUMMARY: json.dumps(summary)}
    return export_onnx(Actor(model), observation_size, Path(out), metadata=metadata)
