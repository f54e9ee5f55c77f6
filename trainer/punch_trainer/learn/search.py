"""Trajectory search (the paper's TTR, Algorithm 1): find the open-loop action sequence with the highest
return for a reward, fast, with no network.

A table holds, for each decision j and DOF k, a Gaussian N(mu_jk, sigma_jk); mu starts at 0 and sigma at
1. Each iteration samples `rollouts` sequences around mu, clipped to [-1, 1]. It runs them all at once on
the training servers, where every action is smoothed (Eq. 1, in the Rust controller), and sums each
sequence's reward. A sequence that beats the best so far becomes mu (the best raw actions: replaying them
reproduces the best trajectory exactly, since the physics is deterministic).

Sigma rule (the paper names only its ingredients: the advantage of each rollout and PPO-style clipping):
1. Each sample i gets a weight w_i = softmax(A_i / s), where A_i = R_i - R_best <= 0 is its advantage and
   the temperature s is the standard deviation of the iteration's returns.
2. The proposed sigma is the weighted spread of the samples around the best trajectory:
   sqrt(sum_i w_i (a_i - mu)^2).
3. The proposal may change sigma by at most a factor of 1 +- epsilon per iteration (the PPO clip), and
   never below `sigma_min`. Epsilon is 0.2 by default; the `swing` preset uses 0.1 (rewards.py says why).

Why: while no sample beats the others, the weights stay flat and the spread stays near the current sigma,
so the search stays wide. Once good samples cluster around the best, their weights dominate and sigma
shrinks toward them, by at most 20% per iteration. A sudden jump of the best cannot make sigma collapse
in one step. The convergence plot (sigma over iterations) in every run shows the effect.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.learn.checkpoint import CheckpointError, default_run_dir, load_checkpoint, save_checkpoint
from punch_trainer.sim.rewards import Reward, Terms, score_terms
from punch_trainer.sim.rollouts import RolloutPool


@dataclass
class SearchArgs:
    reward: str = "straight"
    """a preset (straight, straight100, hook, swing) or FILE.py:FUNCTION"""
    frames: int | None = None
    """episode length in physics frames (default: the reward's)"""
    seed: int = 0
    """seed of the sampling; the physics itself is deterministic"""
    out: Path | None = None
    """run directory (default runs/<reward>__<seed>__<time>)"""
    iterations: int = 150
    """most iterations"""
    rollouts: int = 64
    """sampled trajectories per iteration (n_t)"""
    sigma_init: float = 1.0
    sigma_min: float = 0.02
    clip_epsilon: float | None = None
    """largest relative change of sigma per iteration (PPO-style clip); default: the reward's (0.2, swing 0.1)"""
    smoothing_window: int = 3
    """Eq. 1 window n (1: no smoothing)"""
    plateau_iterations: int = 40
    """stop when the best return has not improved for this many iterations (0: never)"""
    time_budget_s: float | None = None
    """stop after this much wall time"""
    processes: int = 1
    characters_per_process: int = 64
    decision_period: int = 5

    def run_dir(self) -> Path:
        """`out`, or a new runs/<reward>__<seed>__<time>."""
        return self.out or default_run_dir(self.reward, self.seed)


@dataclass
class SearchResult:
    best_actions: np.ndarray  # raw [decisions, 10]
    best_executed: np.ndarray  # after smoothing [decisions, 10]
    best_return: float
    best_features: np.ndarray  # [frames, F]
    best_terms: dict[str, float]
    history: list[dict[str, Any]] = field(default_factory=list)
    feature_names: list[str] = field(default_factory=list)
    best_slot: int = 0  # the character slot (within a process) the best trajectory ran in


def update_sigma(samples: np.ndarray, returns: np.ndarray, mu: np.ndarray, best_return: float, sigma: np.ndarray,
                 clip_epsilon: float, sigma_min: float) -> np.ndarray:
    """The sigma rule of this module's docstring. samples [n, D, 10], returns [n], mu and sigma [D, 10]."""
    advantages = returns - best_return
    temperature = max(float(np.std(returns)), 1e-8)
    weights = np.exp((advantages - advantages.max()) / temperature)
    weights /= weights.sum()
    spread = np.sqrt(np.tensordot(weights, (samples - mu) ** 2, axes=(0, 0)))
    sigma_next: np.ndarray = np.maximum(np.clip(spread, (1 - clip_epsilon) * sigma, (1 + clip_epsilon) * sigma), sigma_min)
    return sigma_next


def evaluate_actions(pool: RolloutPool, reward: Reward, actions: np.ndarray,
                     smoothing_window: int) -> tuple[np.ndarray, Terms, np.ndarray, np.ndarray]:
    """Runs raw action sequences [M, decisions, A] and scores them: (returns [M], per-frame terms,
    features [M, frames, F], executed actions [M, decisions, A])."""
    features, executed = pool.run(actions, smoothing_window)
    returns, terms = score_terms(reward, features, pool.info.feature_names)
    return returns, terms, features, executed


def trajectory_search(args: SearchArgs, reward: Reward, pool: RolloutPool, progress: bool = True,
                      run_dir: Path | None = None) -> SearchResult:
    """Runs TTR on `pool` until a stopping rule fires. With `run_dir` it checkpoints after every iteration
    and first continues from the checkpoint it finds there: mu, sigma, the best so far and the sampler's
    state, so a resumed search ends exactly where an uninterrupted one would."""
    rng = np.random.default_rng(args.seed)
    names = pool.info.feature_names
    clip_epsilon = args.clip_epsilon if args.clip_epsilon is not None else reward.search_clip_epsilon
    decisions = reward.frames // args.decision_period
    action_size = pool.info.action_size

    def returns_of(actions: np.ndarray) -> tuple[np.ndarray, Terms, np.ndarray, np.ndarray]:
        return evaluate_actions(pool, reward, actions, args.smoothing_window)

    saved = load_checkpoint(run_dir, "search") if run_dir is not None else None
    if saved is None:
        mu = np.zeros((decisions, action_size), dtype=np.float32)
        sigma = np.full((decisions, action_size), args.sigma_init, dtype=np.float64)
        returns, terms, features, executed = returns_of(mu[None])
        best = SearchResult(mu.copy(), executed[0], float(returns[0]), features[0],
                            {k: float(v[0].sum()) for k, v in terms.items()}, feature_names=names)
        done_iterations, rollouts_done, last_improvement, elapsed_before, stopped = 0, 1, 0, 0.0, False
    else:
        mu, sigma = saved["mu"].numpy(), saved["sigma"].numpy()
        if mu.shape != (decisions, action_size):
            raise CheckpointError(f"the checkpoint in {run_dir} holds {mu.shape[0]} decisions; this search has {decisions}")
        rng.bit_generator.state = saved["rng_state"]
        best = SearchResult(saved["best_actions"].numpy(), saved["best_executed"].numpy(), saved["best_return"],
                            saved["best_features"].numpy(), saved["best_terms"], saved["history"], names, saved["best_slot"])
        done_iterations, rollouts_done, last_improvement = saved["iteration"], saved["rollouts"], saved["last_improvement"]
        elapsed_before, stopped = saved["elapsed_s"], saved["stopped"]
    if stopped:
        return best

    start = time.perf_counter() - elapsed_before
    bar = tqdm(range(done_iterations + 1, args.iterations + 1), desc=f"search {reward.name}", unit="it",
               initial=done_iterations, total=args.iterations, disable=not progress)
    for iteration in bar:
        samples = np.clip(mu + sigma * rng.standard_normal((args.rollouts, decisions, action_size)), -1.0, 1.0).astype(np.float32)
        returns, terms, features, executed = returns_of(samples)
        rollouts_done += args.rollouts
        top = int(np.argmax(returns))
        if returns[top] > best.best_return:
            mu = samples[top].copy()
            best = SearchResult(mu.copy(), executed[top], float(returns[top]), features[top],
                                {k: float(v[top].sum()) for k, v in terms.items()}, best.history, names,
                                best_slot=top % pool.characters_per_process)
            last_improvement = iteration
        sigma = update_sigma(samples, returns, mu, best.best_return, sigma, clip_epsilon, args.sigma_min)
        elapsed = time.perf_counter() - start
        best.history.append({
            "iteration": iteration, "rollouts": rollouts_done, "elapsed_s": round(elapsed, 4),
            "best_return": best.best_return, "mean_return": float(returns.mean()), "sigma_mean": float(sigma.mean()),
            **{f"best_{k}": v for k, v in best.best_terms.items()},
        })
        bar.set_postfix(best=f"{best.best_return:.3f}", rollouts_per_s=f"{rollouts_done / elapsed:.0f}")
        stopped = (iteration == args.iterations
                   or bool(args.plateau_iterations and iteration - last_improvement >= args.plateau_iterations)
                   or (args.time_budget_s is not None and elapsed >= args.time_budget_s))
        if run_dir is not None:
            save_checkpoint(run_dir, "search", {
                "iteration": iteration, "mu": mu, "sigma": sigma, "rng_state": rng.bit_generator.state,
                "best_actions": best.best_actions, "best_executed": best.best_executed, "best_return": best.best_return,
                "best_features": best.best_features, "best_terms": best.best_terms, "best_slot": best.best_slot,
                "history": best.history, "rollouts": rollouts_done, "last_improvement": last_improvement,
                "elapsed_s": elapsed, "stopped": stopped})
        if stopped:
            break
    bar.close()
    return best
