"""Supervised pretraining from trajectory datasets (no simulation): behaviour cloning of the mean, a set
initial sigma, and the critic fitted to the returns-to-go. One dataset (the paper) or several (its future
work) are concatenated."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from punch_trainer.learn.policy import ActorCritic


@dataclass
class PretrainArgs:
    epochs: int = 1500
    """passes over the datasets"""
    learning_rate: float = 3e-3
    """Adam's learning rate"""
    initial_sigma: float = 0.1
    """sigma the actor starts A2C with (a bias on its sigma head)"""
    gamma: float = 1.0
    """discount of the returns-to-go the critic learns (episodes are short and fixed)"""
    seed: int = 0
    """seed of the network's initial weights and the batches"""


def pretrain(model: ActorCritic, data: dict[str, np.ndarray], args: PretrainArgs, progress: bool = True,
             statistics_observations: np.ndarray | None = None) -> list[dict[str, Any]]:
    """Fits the actor's mean to the dataset's actions and the critic to the returns-to-go; sets sigma. The
    observation normalisation comes from the dataset's observations and `statistics_observations` (what
    the policy will meet beyond them: a bag that was never moved in the dataset must not look fixed)."""
    torch.manual_seed(args.seed)
    extra = [] if statistics_observations is None else [statistics_observations]
    model.set_normalization(np.concatenate([data["observations"], *extra]))
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


def fit_critic(model: ActorCritic, data: dict[str, np.ndarray], epochs: int = 500, learning_rate: float = 3e-3,
               progress: bool = True) -> list[dict[str, Any]]:
    """Fits the critic alone to the datasets' returns-to-go, leaving the actor and the normalisation as they are:
    for a warm start from a policy file, which holds no critic (learn/warm_start.py)."""
    obs = torch.as_tensor(data["observations"])
    targets = torch.as_tensor(data["returns_to_go"])
    optimizer = torch.optim.Adam(model.critic.parameters(), lr=learning_rate)
    history = []
    for epoch in tqdm(range(1, epochs + 1), desc="fit critic", unit="epoch", disable=not progress):
        critic_loss = torch.mean((model.value(obs) - targets) ** 2)
        optimizer.zero_grad()
        critic_loss.backward()
        optimizer.step()
        if epoch % 50 == 0 or epoch == epochs:
            history.append({"epoch": epoch, "critic_mse": critic_loss.item()})
    return history
