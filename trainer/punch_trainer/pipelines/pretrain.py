"""`punch pretrain`: a policy pretrained on one or several trajectory datasets, with no simulation, exported
with the datasets' policy contract."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from punch_trainer.learn.dataset import load_datasets
from punch_trainer.learn.export import export_policy
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.pretrain import PretrainArgs, pretrain


@dataclass(frozen=True)
class PretrainResult:
    policy: Path
    """the exported policy file"""
    decisions: int
    """decisions (dataset rows) it was pretrained on"""
    final_actor_mse: float
    """the actor's mean squared error to the datasets' actions after the last epoch"""


def pretrain_datasets(datasets: list[Path], out: Path, args: PretrainArgs) -> PretrainResult:
    """Pretrains an actor-critic on `datasets` and exports it to `out`, verified."""
    data = load_datasets(datasets)
    model = ActorCritic(data["observations"].shape[1], data["actions"].shape[1], seed=args.seed)
    history = pretrain(model, data, args)
    # A policy names its reward when every dataset had the same one (punch replay scores with it).
    rewards = data["reward_names"]
    final_mse = float(history[-1]["actor_mse"])
    summary = {"pretrained_on": [str(path) for path in datasets], "decisions": len(data["actions"]),
               "final_actor_mse": final_mse}
    path = export_policy(model, out, contract=data["policy_metadata"], reward=rewards[0] if len(rewards) == 1 else "",
                         summary=summary)
    return PretrainResult(policy=path, decisions=len(data["actions"]), final_actor_mse=final_mse)
