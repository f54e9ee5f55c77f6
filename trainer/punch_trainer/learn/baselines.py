"""Baselines for the trajectory search, on the same environment, smoothing and batch size: the
cross-entropy method (CEM) and CMA-ES (the `cmaes` package). Both optimise the whole raw action sequence
(decisions x 10 values in [-1, 1]) and report the same history rows as TTR."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from cmaes import CMA, SepCMA

from punch_trainer.learn.search import SearchArgs, evaluate_actions
from punch_trainer.reward.rewards import Reward
from punch_trainer.sim.rollouts import RolloutPool

CEM_ELITE_FRACTION = 0.1
CMA_SIGMA_INIT = 0.5
CMA_FULL_COVARIANCE_MAX_DIM = 100  # larger problems use the separable (diagonal) variant


def _row(iteration: int, rollouts: int, start: float, best: float, returns: np.ndarray) -> dict[str, Any]:
    return {"iteration": iteration, "rollouts": rollouts, "elapsed_s": round(time.perf_counter() - start, 4),
            "best_return": best, "mean_return": float(returns.mean())}


def cem(args: SearchArgs, reward: Reward, pool: RolloutPool) -> list[dict[str, Any]]:
    """CEM: a diagonal Gaussian refitted to the best 10% of each population."""
    rng = np.random.default_rng(args.seed)
    shape = (reward.frames // args.decision_period, pool.info.action_size)
    mean, std = np.zeros(shape), np.full(shape, args.sigma_init)
    elites = max(2, int(round(CEM_ELITE_FRACTION * args.rollouts)))
    start, best, rollouts, history = time.perf_counter(), -np.inf, 0, []
    for iteration in range(1, args.iterations + 1):
        samples = np.clip(mean + std * rng.standard_normal((args.rollouts, *shape)), -1, 1).astype(np.float32)
        returns = evaluate_actions(pool, reward, samples, args.smoothing_window)[0]
        rollouts += args.rollouts
        best = max(best, float(returns.max()))
        top = samples[np.argsort(returns)[-elites:]]
        mean, std = top.mean(axis=0), np.maximum(top.std(axis=0), args.sigma_min)
        history.append(_row(iteration, rollouts, start, best, returns))
    return history


def cma_es(args: SearchArgs, reward: Reward, pool: RolloutPool) -> list[dict[str, Any]]:
    """CMA-ES over the flattened sequence, bounded to [-1, 1], with the same population as TTR."""
    shape = (reward.frames // args.decision_period, pool.info.action_size)
    dim = shape[0] * shape[1]
    bounds = np.tile([-1.0, 1.0], (dim, 1))
    kind = CMA if dim <= CMA_FULL_COVARIANCE_MAX_DIM else SepCMA
    optimizer = kind(mean=np.zeros(dim), sigma=CMA_SIGMA_INIT, bounds=bounds, seed=args.seed, population_size=args.rollouts)
    start, best, rollouts, history = time.perf_counter(), -np.inf, 0, []
    for iteration in range(1, args.iterations + 1):
        candidates = np.stack([optimizer.ask() for _ in range(optimizer.population_size)])
        returns = evaluate_actions(pool, reward, candidates.reshape(-1, *shape).astype(np.float32), args.smoothing_window)[0]
        rollouts += len(candidates)
        best = max(best, float(returns.max()))
        optimizer.tell(list(zip(candidates, -returns)))  # cmaes minimises
        history.append(_row(iteration, rollouts, start, best, returns))
    return history
