"""A2C in the simulator (paper Algorithm 2): the agent samples its own actions, closed loop, for N
characters at once, and the actor-critic is updated with PPO's clipped objective, as the paper describes.

Advantage estimates (`advantage`):
- "gae": generalised advantage estimation (lambda 0.95) on the critic. This is the default, chosen by the
  comparison in BENCHMARKS.md.
- "paper": the paper's formula as printed: the best episode return so far minus this episode's return,
  the same for every step of the episode.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass

import numpy as np
import torch
from tqdm import tqdm

from punch_trainer.env import PunchVectorEnv
from punch_trainer.policy import ActorCritic
from punch_trainer.rewards import Reward, evaluate, total


@dataclass
class A2CArgs:
    updates: int = 60
    """policy updates; each runs one episode on every character"""
    characters: int = 32
    learning_rate: float = 3e-4
    gamma: float = 1.0
    gae_lambda: float = 0.95
    clip: float = 0.2
    epochs: int = 4
    """passes over each batch (the clipped ratio matters from the second on)"""
    entropy_coef: float = 0.0
    value_coef: float = 0.5
    advantage: str = "gae"
    """'gae' or 'paper'"""
    smoothing_window: int = 3
    time_budget_s: float | None = None
    seed: int = 0


def decision_rewards(reward: Reward, features: np.ndarray, names: list[str]) -> np.ndarray:
    """Rewards per character for one decision: features [N, frames_per_decision, F] -> [N]."""
    return total(evaluate(reward, features, names)).sum(axis=-1)


def evaluate_noise_free(model: ActorCritic, env: PunchVectorEnv, reward: Reward) -> float:
    """Return of the policy's mean actions (every character does the same, so character 0 is enough)."""
    obs, _ = env.reset()
    episode = 0.0
    while True:
        with torch.no_grad():
            mean, _ = model(torch.as_tensor(obs))
        obs, _, terminated, truncated, info = env.step(mean.numpy())
        episode += float(decision_rewards(reward, info["features"][:1], env.feature_names)[0])
        if terminated[0] or truncated[0]:
            return episode


def train_a2c(model: ActorCritic, reward: Reward, args: A2CArgs, env: PunchVectorEnv, progress: bool = True,
              start_rollouts: int = 0) -> tuple[ActorCritic, list[dict]]:
    """Trains in place and returns the parameters with the best noise-free return, with the history."""
    torch.manual_seed(args.seed)
    optimizer = torch.optim.Adam(model.parameters(), lr=args.learning_rate)
    names = env.feature_names
    best_model, best_eval = copy.deepcopy(model), evaluate_noise_free(model, env, reward)
    best_episode_return = -np.inf
    history = [{"update": 0, "episodes": 0, "env_steps": start_rollouts, "elapsed_s": 0.0, "mean_return": float("nan"), "eval_return": best_eval}]
    start, env_steps, episodes = time.perf_counter(), start_rollouts, 0
    for update in tqdm(range(1, args.updates + 1), desc=f"a2c ({args.advantage})", unit="update", disable=not progress):
        obs, _ = env.reset()
        batch_obs, batch_actions, batch_logp, batch_values, batch_rewards = [], [], [], [], []
        done = np.zeros(env.num_envs, dtype=bool)
        while not done.all():
            obs_t = torch.as_tensor(obs)
            with torch.no_grad():
                dist = model.distribution(obs_t)
                action = dist.sample()
                logp = dist.log_prob(action).sum(-1)
                value = model.value(obs_t)
            obs, _, terminated, truncated, info = env.step(action.clamp(-1, 1).numpy())
            batch_obs.append(obs_t)
            batch_actions.append(action)
            batch_logp.append(logp)
            batch_values.append(value)
            batch_rewards.append(torch.as_tensor(decision_rewards(reward, info["features"], names), dtype=torch.float32))
            done = terminated | truncated
            env_steps += env.num_envs
        episodes += env.num_envs
        rewards = torch.stack(batch_rewards)  # [T, N]
        values = torch.stack(batch_values)
        episode_returns = rewards.sum(0)
        best_episode_return = max(best_episode_return, float(episode_returns.max()))
        if args.advantage == "paper":
            advantages = (best_episode_return - episode_returns).expand_as(rewards).clone()
            returns = torch.flip(torch.cumsum(torch.flip(rewards, [0]), 0), [0])
        else:
            advantages = torch.zeros_like(rewards)
            running = torch.zeros(env.num_envs)
            for t in range(rewards.shape[0] - 1, -1, -1):
                next_value = values[t + 1] if t + 1 < rewards.shape[0] else torch.zeros(env.num_envs)
                delta = rewards[t] + args.gamma * next_value - values[t]
                running = delta + args.gamma * args.gae_lambda * running
                advantages[t] = running
            returns = advantages + values
        flat = lambda x: x.reshape(-1, *x.shape[2:])  # noqa: E731
        b_obs, b_actions, b_logp = flat(torch.stack(batch_obs)), flat(torch.stack(batch_actions)), flat(torch.stack(batch_logp))
        b_adv, b_returns = flat(advantages), flat(returns)
        b_adv = (b_adv - b_adv.mean()) / (b_adv.std() + 1e-8)
        for _ in range(args.epochs):
            dist = model.distribution(b_obs)
            ratio = torch.exp(dist.log_prob(b_actions).sum(-1) - b_logp)
            policy_loss = -torch.min(ratio * b_adv, torch.clamp(ratio, 1 - args.clip, 1 + args.clip) * b_adv).mean()
            value_loss = ((model.value(b_obs) - b_returns) ** 2).mean()
            loss = policy_loss + args.value_coef * value_loss - args.entropy_coef * dist.entropy().sum(-1).mean()
            optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 0.5)
            optimizer.step()
        evaluation = evaluate_noise_free(model, env, reward)
        if evaluation > best_eval:
            best_eval, best_model = evaluation, copy.deepcopy(model)
        elapsed = time.perf_counter() - start
        history.append({"update": update, "episodes": episodes, "env_steps": env_steps, "elapsed_s": round(elapsed, 3),
                        "mean_return": float(episode_returns.mean()), "eval_return": evaluation})
        if args.time_budget_s is not None and elapsed >= args.time_budget_s:
            break
    return best_model, history
