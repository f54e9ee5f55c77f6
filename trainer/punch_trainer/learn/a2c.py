"""A2C in the simulator (paper Algorithm 2): the agent samples its own actions, closed loop, for N
characters at once, and the actor-critic is updated with PPO's clipped objective, as the paper describes.

Advantage estimates (`advantage`):
- "gae": generalised advantage estimation (lambda 0.95) on the critic. This is the default, chosen by the
  comparison in BENCHMARKS.md.
- "paper": the paper's formula as printed: the best episode return so far minus this episode's return,
  the same for every step of the episode.

Every update's row of the history carries, besides the returns, what says why a run learns or does not:
`policy_loss`, `value_loss`, `entropy` (of the action distribution, summed over the actions) and `sigma_mean`
(the policy's sigma on the batch's observations, the floor included), each the mean over the update's epochs;
and per reward term `reward/<term>`, the term's part of the mean episode return of the update's episodes."""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from punch_trainer.learn.checkpoint import CheckpointError, flag, load_checkpoint, number, save_checkpoint
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.volume import validate
from punch_trainer.reward.rewards import EpisodeScorer, Reward
from punch_trainer.sim.conditions import EpisodeConditions, EpisodeStart
from punch_trainer.sim.env import PunchVectorEnv
from punch_trainer.sim.server_group import SimulatorRestarts


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
    sigma_floor: float = 0.0
    """the least sigma actions are sampled with, in collection and in the update: keeps exploring and
    keeps the policy seeing (and correcting) noisy decisions after its learned sigma has shrunk. A reward's
    style caps it where the style narrows the search (reward/style.py: the guard arm and the waist's flexion),
    since noise there alone costs a styled punch everything it earns."""
    time_budget_s: float | None = None
    seed: int = 0
    snapshot_every: int = 0
    """hand the model to `on_snapshot` every this many updates (0: never)"""


def evaluate_noise_free(model: ActorCritic, env: PunchVectorEnv, reward: Reward) -> float:
    """Return of the policy's mean actions (every character does the same, so character 0 is enough)."""
    obs, _ = env.reset()
    episode, scorer = 0.0, EpisodeScorer(reward, env.feature_names)
    while True:
        with torch.no_grad():
            mean, _ = model(torch.as_tensor(obs))
        obs, _, terminated, truncated, info = env.step(mean.numpy())
        episode += float(scorer.add(info["features"][:1])[0][0])
        if terminated[0] or truncated[0]:
            return episode


@dataclass(frozen=True)
class EpisodeBatch:
    """One episode on each of N characters, T decisions long, as `collect_episodes` sampled it. Every tensor is
    indexed [decision, character, ...]."""

    observations: torch.Tensor
    """[T, N, observation size]: what the policy saw before each decision"""
    actions: torch.Tensor
    """[T, N, action size]: the sampled actions, before clamping to [-1, 1] (the simulator played them clamped)"""
    log_probs: torch.Tensor
    """[T, N]: the log-probability of each sampled action (summed over its components) under the sampling policy"""
    values: torch.Tensor
    """[T, N]: the critic's value of each observation"""
    rewards: torch.Tensor
    """[T, N]: each decision's reward, the reward function's score of the frames it played (with a style, given
    the episode's frames before them: reward/rewards.py, EpisodeScorer)"""
    term_rewards: dict[str, torch.Tensor]
    """the reward function's term name -> [T, N]: that term's part of `rewards`"""

    def episode_returns(self) -> torch.Tensor:
        """[N]: each character's episode return."""
        return self.rewards.sum(0)


def style_sigma_cap(reward: Reward, action_size: int) -> torch.Tensor | None:
    """The largest sigma A2C samples each degree of freedom with under the reward's style (the search's cap),
    or None without a style."""
    if reward.style is None:
        return None
    return torch.as_tensor(reward.style.search_sigma_cap(action_size), dtype=torch.float32)


def collect_episodes(model: ActorCritic, env: PunchVectorEnv, reward: Reward,
                     options: EpisodeStart | None = None, sigma_floor: float = 0.0) -> EpisodeBatch:
    """One episode on every character with actions sampled from the policy (reset with `options`: bag
    placements, lead-ins)."""
    obs, _ = env.reset(options=options)
    observations: list[torch.Tensor] = []
    actions: list[torch.Tensor] = []
    log_probs: list[torch.Tensor] = []
    values: list[torch.Tensor] = []
    rewards: list[torch.Tensor] = []
    term_rewards: dict[str, list[torch.Tensor]] = {}
    done = np.zeros(env.num_envs, dtype=bool)
    scorer = EpisodeScorer(reward, env.feature_names)
    cap = style_sigma_cap(reward, env.info.action_size)
    while not done.all():
        obs_t = torch.as_tensor(obs)
        with torch.no_grad():
            dist = model.distribution(obs_t, sigma_floor, cap)
            action = dist.sample()
            logp = dist.log_prob(action).sum(-1)
            value = model.value(obs_t)
        obs, _, terminated, truncated, info = env.step(action.clamp(-1, 1).numpy())
        step_returns, step_terms = scorer.add(info["features"])
        observations.append(obs_t)
        actions.append(action)
        log_probs.append(logp)
        values.append(value)
        rewards.append(torch.as_tensor(step_returns, dtype=torch.float32))
        for term, term_step_rewards in step_terms.items():
            term_rewards.setdefault(term, []).append(torch.as_tensor(term_step_rewards))
        done = terminated | truncated
    return EpisodeBatch(observations=torch.stack(observations), actions=torch.stack(actions), log_probs=torch.stack(log_probs),
                        values=torch.stack(values), rewards=torch.stack(rewards),
                        term_rewards={term: torch.stack(items) for term, items in term_rewards.items()})


def advantages_and_returns(rewards: torch.Tensor, values: torch.Tensor, best_episode_return: float,
                           args: A2CArgs) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-decision advantages and critic targets [T, N] (module docstring: `advantage`)."""
    if args.advantage == "paper":
        advantages = (best_episode_return - rewards.sum(0)).expand_as(rewards).clone()
        return advantages, torch.flip(torch.cumsum(torch.flip(rewards, [0]), 0), [0])
    advantages = torch.zeros_like(rewards)
    running = torch.zeros(rewards.shape[1])
    for t in range(rewards.shape[0] - 1, -1, -1):
        next_value = values[t + 1] if t + 1 < rewards.shape[0] else torch.zeros(rewards.shape[1])
        delta = rewards[t] + args.gamma * next_value - values[t]
        running = delta + args.gamma * args.gae_lambda * running
        advantages[t] = running
    return advantages, advantages + values


def restore_a2c(saved: dict[str, Any], model: ActorCritic, optimizer: torch.optim.Optimizer, args: A2CArgs
                ) -> tuple[ActorCritic, float, float, list[dict[str, Any]], tuple[int, float, bool]]:
    """An A2C checkpoint into `model` and `optimizer`, every value checked first (parameters finite, numbers in
    range): the best model, best noise-free return, best episode return, history and (update, elapsed s,
    stopped). CheckpointError for anything that does not fit."""
    try:
        update = number(saved, "update", 1, args.updates, integer=True)
        elapsed_s = number(saved, "elapsed_s", 0.0, 1e9)
        stopped = flag(saved, "stopped")
        best_eval = float(number(saved, "best_eval", -1e300, 1e300))
        best_episode_return = float(number(saved, "best_episode_return", -1e300, 1e300))
        history = saved["history"]
        if not isinstance(history, list) or len(history) != update + 1 or not all(isinstance(h, dict) for h in history):
            raise CheckpointError(f"the checkpoint's history does not hold one entry per update ({update}) and the start")
        for name in ("model", "best_model"):
            parameters = saved[name]
            if not isinstance(parameters, dict) or not all(isinstance(t, torch.Tensor) and bool(torch.isfinite(t).all())
                                                           for t in parameters.values()):
                raise CheckpointError(f"the checkpoint's {name} holds parameters that are not finite numbers")
        rng_state = saved["torch_rng_state"]
        if not isinstance(rng_state, torch.Tensor) or rng_state.dtype != torch.uint8:
            raise CheckpointError("the checkpoint's random state is not a random state")
        model.load_state_dict(saved["model"])
        optimizer.load_state_dict(saved["optimizer"])
        best_model = copy.deepcopy(model)
        best_model.load_state_dict(saved["best_model"])
        torch.set_rng_state(rng_state)
    except CheckpointError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, RuntimeError) as error:  # any other shape of damage
        raise CheckpointError(f"the checkpoint is not what A2C writes: {type(error).__name__}: {error}") from None
    return best_model, best_eval, best_episode_return, history, (update, elapsed_s, stopped)


def train_a2c(model: ActorCritic, reward: Reward, args: A2CArgs, env: PunchVectorEnv, progress: bool = True,
              start_rollouts: int = 0, run_dir: Path | None = None, max_restarts: int = 3,
              conditions: Callable[[int, int], EpisodeStart] | None = None,
              validation: list[EpisodeConditions] | EpisodeStart | None = None,
              on_snapshot: Callable[[int, ActorCritic], None] | None = None) -> tuple[ActorCritic, list[dict[str, Any]]]:
    """Trains in place and returns the parameters with the best noise-free return, with the history.

    `conditions(count, update)` gives each update's reset options (training over the reach volume: random
    placements, swinging bags, lead-ins); the noise-free return is then the mean over the fixed `validation`
    placements (and `eval_success` their success rate), else character 0's at the default placement.

    With `run_dir` it checkpoints after every update (model, optimizer, best model, history and the random
    state) and first continues from the checkpoint it finds there. A Godot process that crashes, is killed or
    hangs during an update is restarted, and the update's episodes run again with the same random numbers, so
    either way the result is the one an uninterrupted run gives. `on_snapshot(update, model)` sees the model as
    it is every `args.snapshot_every` updates (and after the last)."""
    torch.manual_seed(args.seed)

    def evaluate() -> tuple[float, float | None]:
        if validation is None:
            return evaluate_noise_free(model, env, reward), None
        result = validate(model, env, reward, validation)
        return result.mean_return, result.success_rate

    optimizer = torch.optim.Adam(model.parameters(), lr=args.learning_rate)
    sigma_cap = style_sigma_cap(reward, env.info.action_size)
    restarts = SimulatorRestarts(env.restart, max_restarts)
    saved = load_checkpoint(run_dir, "a2c") if run_dir is not None else None
    if saved is None:
        best_eval, eval_success = restarts.run(evaluate)
        best_model, best_episode_return = copy.deepcopy(model), -np.inf
        history: list[dict[str, Any]] = [{"update": 0, "episodes": 0, "env_steps": start_rollouts, "elapsed_s": 0.0,
                                          "mean_return": float("nan"), "eval_return": best_eval, "eval_success": eval_success}]
        done_updates, elapsed_before, stopped = 0, 0.0, False
    else:
        best_model, best_eval, best_episode_return, history, (done_updates, elapsed_before, stopped) = restore_a2c(
            saved, model, optimizer, args)
    if stopped:
        return best_model, history

    start = time.perf_counter() - elapsed_before
    for update in tqdm(range(done_updates + 1, args.updates + 1), desc=f"a2c ({args.advantage})", unit="update",
                       initial=done_updates, total=args.updates, disable=not progress):
        rng_state = torch.get_rng_state()
        options = conditions(env.num_envs, update) if conditions is not None else None

        def collect(rng_state: torch.Tensor = rng_state, options: EpisodeStart | None = options) -> EpisodeBatch:
            torch.set_rng_state(rng_state)  # a rerun after a restart samples the same actions
            return collect_episodes(model, env, reward, options, args.sigma_floor)

        batch = restarts.run(collect)
        episode_returns = batch.episode_returns()
        best_episode_return = max(best_episode_return, float(episode_returns.max()))
        advantages, returns = advantages_and_returns(batch.rewards, batch.values, best_episode_return, args)
        flat = lambda x: x.reshape(-1, *x.shape[2:])
        b_obs, b_actions, b_logp = flat(batch.observations), flat(batch.actions), flat(batch.log_probs)
        b_adv, b_returns = flat(advantages), flat(returns)
        b_adv = (b_adv - b_adv.mean()) / (b_adv.std() + 1e-8)
        per_epoch: dict[str, list[float]] = {"policy_loss": [], "value_loss": [], "entropy": [], "sigma_mean": []}
        for _ in range(args.epochs):
            dist = model.distribution(b_obs, args.sigma_floor, sigma_cap)
            ratio = torch.exp(dist.log_prob(b_actions).sum(-1) - b_logp)
            policy_loss = -torch.min(ratio * b_adv, torch.clamp(ratio, 1 - args.clip, 1 + args.clip) * b_adv).mean()
            value_loss = ((model.value(b_obs) - b_returns) ** 2).mean()
            entropy = dist.entropy().sum(-1).mean()
            loss = policy_loss + args.value_coef * value_loss - args.entropy_coef * entropy
            optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 0.5)
            optimizer.step()
            for key, measured in (("policy_loss", policy_loss), ("value_loss", value_loss), ("entropy", entropy),
                               ("sigma_mean", dist.scale.mean())):
                per_epoch[key].append(float(measured.detach()))
        diagnostics = {key: float(np.mean(values)) for key, values in per_epoch.items()}
        diagnostics |= {f"reward/{term}": float(term_rewards.sum(0).mean()) for term, term_rewards in batch.term_rewards.items()}
        evaluation, eval_success = restarts.run(evaluate)
        if evaluation > best_eval:
            best_eval, best_model = evaluation, copy.deepcopy(model)
        elapsed = time.perf_counter() - start
        steps = batch.rewards.numel()
        history.append({"update": update, "episodes": history[-1]["episodes"] + env.num_envs,
                        "env_steps": history[-1]["env_steps"] + steps, "elapsed_s": round(elapsed, 3),
                        "mean_return": float(episode_returns.mean()), "eval_return": evaluation, "eval_success": eval_success,
                        **diagnostics})
        stopped = update == args.updates or (args.time_budget_s is not None and elapsed >= args.time_budget_s)
        if on_snapshot is not None and args.snapshot_every and (update % args.snapshot_every == 0 or stopped):
            on_snapshot(update, model)
        if run_dir is not None:
            save_checkpoint(run_dir, "a2c", {
                "update": update, "model": model.state_dict(), "optimizer": optimizer.state_dict(),
                "best_model": best_model.state_dict(), "best_eval": best_eval, "best_episode_return": best_episode_return,
                "history": history, "elapsed_s": elapsed, "stopped": stopped, "torch_rng_state": torch.get_rng_state()})
        if stopped:
            break
    return best_model, history
