"""Supervised pretraining from trajectory datasets (no simulation): behaviour cloning of the mean, a set
initial sigma, and the critic fitted to the returns-to-go. One dataset (the paper) or several (its future
work) are concatenated."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from punch_trainer.policy import ActorCritic


@dataclass
class PretrainArgs:
    epochs: int = 2000
    learning_rate: float = 3e-3
    initial_sigma: float = 0.1
    """sigma the actor starts A2C with (a bias on its sigma head)"""
    gamma: float = 1.0
    """discount of the returns-to-go the critic learns (episodes are short and fixed)"""
    seed: int = 0


def load_datasets(paths: list[Path]) -> dict[str, np.ndarray]:
    """Concatenates the decision-level arrays of several datasets (they must share the spec)."""
    parts = [dict(np.load(path)) for path in paths]
    hashes = {str(p["spec_hash"]) for p in parts}
    if len(hashes) != 1:
        raise ValueError(f"datasets come from different observation specs: {sorted(hashes)}")
    out = {key: np.concatenate([p[key] for p in parts]) for key in ("observations", "actions", "rewards")}
    out["returns_to_go"] = np.concatenate([returns_to_go(p["rewards"], 1.0) for p in parts])
    out["spec_hash"] = parts[0]["spec_hash"]
    return out


def returns_to_go(rewards: np.ndarray, gamma: float) -> np.ndarray:
    out = np.zeros_like(rewards, dtype=np.float64)
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        running = rewards[t] + gamma * running
        out[t] = running
    return out.astype(np.float32)


def pretrain(model: ActorCritic, data: dict[str, np.ndarray], args: PretrainArgs, progress: bool = True) -> list[dict]:
    """Fits the actor's mean to the dataset's actions and the critic to the returns-to-go; sets sigma."""
    torch.manual_seed(args.seed)
    model.set_normalization(data["observations"])
    obs = torch.as_tensor(data["observations"])
    actions = torch.as_tensor(data["actions"])
    targets = torch.as_tensor(data["returns_to_go"])
    with torch.no_grad():
        model.log_sigma_head.weight.zero_()
        model.log_sigma_head.bias.fill_(float(np.log(args.initial_sigma)))
    parameters = list(model.actor.parameters()) + list(model.mean_head.parameters()) + list(model.critic.parameters())
    optimizer = torch.optim.Adam(parameters, lr=args.learning_rate)
    history = []
    for epoch in tqdm(range(1, args.epochs + 1), desc="pretrain", unit="epoch", disable=not progress):
        mean, _ = model(obs)
        actor_loss = torch.mean((mean - actions) ** 2)
        critic_loss = torch.mean((model.value(obs) - targets) ** 2)
        optimizer.zero_grad()
        (actor_loss + critic_loss).backward()
        optimizer.step()
        if epoch % 50 == 0 or epoch == args.epochs:
            history.append({"epoch": epoch, "actor_mse": actor_loss.item(), "critic_mse": critic_loss.item()})
    return history
