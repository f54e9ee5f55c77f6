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

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.learn.checkpoint import CheckpointError, array, default_run_dir, flag, load_checkpoint, number, save_checkpoint
from punch_trainer.options import bounds
from punch_trainer.reward.rewards import Reward, Terms, score_terms
from punch_trainer.reward.style import MAX_WEIGHT as MAX_STYLE_WEIGHT
from punch_trainer.sim.conditions import EpisodeConditions
from punch_trainer.sim.rollouts import RolloutPool


@dataclass
class SearchArgs:
    reward: str = "straight"
    """a preset (the paper's straight, straight100, hook and swing, and the moves' rewards: README, "Training your own
    punch") or FILE.py:FUNCTION"""
    style: str = "none"
    """the motion style added to the reward (docs/style.md): none, the reward alone (the paper's search); boxing, a
    human's punch (`punch train`'s default); or FILE.toml:NAME, a style of a file (recipes/styles.toml)"""
    style_weight: float = field(default=1.0, metadata=bounds(0.0, MAX_STYLE_WEIGHT))
    """how strongly the style holds (1: as measured in docs/style.md)"""
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
    """every table entry's sigma at the start"""
    sigma_min: float = 0.02
    """the least sigma an entry narrows to"""
    clip_epsilon: float | None = None
    """largest relative change of sigma per iteration (PPO-style clip); default: the reward's (0.2, swing 0.1)"""
    smoothing_window: int = 3
    """Eq. 1 window n (1: no smoothing)"""
    plateau_iterations: int = 40
    """stop when the best return has not improved for this many iterations (0: never)"""
    time_budget_s: float | None = None
    """stop after this much wall time"""
    processes: int = 1
    """Godot processes (with --ray: Ray workers, docs/cluster.md)"""
    characters_per_process: int = 64
    """characters simulated at once in each process"""
    decision_period: int = 5
    """physics frames per decision (the training server's)"""

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


SearchCounters = tuple[int, int, int, float, bool]


def restore_search(saved: dict[str, Any], args: SearchArgs, rng: np.random.Generator, table_shape: tuple[int, int, int],
                   feature_count: int, names: list[str], characters_per_process: int
                   ) -> tuple[np.ndarray, np.ndarray, list[SearchResult], list[dict[str, Any]], SearchCounters]:
    """A search's checkpoint, every value checked (types, shapes, ranges, finiteness) before it is used:
    the tables mu and sigma, the bests, the history and (iteration, rollouts, last improvement, elapsed s,
    stopped). CheckpointError for anything that does not fit; `rng` takes the saved sampler state."""
    count, decisions, action_size = table_shape
    try:
        mu = array(saved, "mu", table_shape, -1.0, 1.0)
        sigma = array(saved, "sigma", table_shape, 0.0, 1e6)
        iteration = number(saved, "iteration", 1, args.iterations, integer=True)
        rollouts = number(saved, "rollouts", 1, 1e15, integer=True)
        last_improvement = number(saved, "last_improvement", 0, iteration, integer=True)
        elapsed_s = number(saved, "elapsed_s", 0.0, 1e9)
        stopped = flag(saved, "stopped")
        history = saved["history"]
        if not isinstance(history, list) or len(history) != iteration or not all(isinstance(h, dict) for h in history):
            raise CheckpointError(f"the checkpoint's history does not hold one entry per iteration ({iteration})")
        for entry in history:
            for key, value in entry.items():
                if not isinstance(key, str) or isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                    raise CheckpointError(f"the checkpoint's history holds {key!r}: {value!r}, not a finite number")
        saved_bests = saved["bests"]
        if not isinstance(saved_bests, list) or len(saved_bests) != count:
            raise CheckpointError(f"the checkpoint holds {len(saved_bests) if isinstance(saved_bests, list) else 'no'} bests; "
                                  f"this search has {count} placements")
        bests = []
        for best in saved_bests:
            if not isinstance(best, dict) or not isinstance(best.get("terms"), dict):
                raise CheckpointError("the checkpoint's bests are not what a search writes")
            terms = {str(k): number(best["terms"], k, -1e300, 1e300) for k in best["terms"]}
            bests.append(SearchResult(array(best, "actions", (decisions, action_size), -1.0, 1.0),
                                      array(best, "executed", (decisions, action_size), -1.0, 1.0),
                                      float(number(best, "return", -1e300, 1e300)),
                                      array(best, "features", (decisions * args.decision_period, feature_count)),
                                      terms, history, names, number(best, "slot", 0, characters_per_process - 1, integer=True)))
        rng.bit_generator.state = saved["rng_state"]
    except CheckpointError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, RuntimeError) as error:  # any other shape of damage
        raise CheckpointError(f"the checkpoint is not what a search writes: {type(error).__name__}: {error}") from None
    return mu, sigma, bests, history, (iteration, rollouts, last_improvement, elapsed_s, stopped)


def trajectory_search(args: SearchArgs, reward: Reward, pool: RolloutPool, progress: bool = True,
                      run_dir: Path | None = None) -> SearchResult:
    """Runs TTR at the spec's default placement on `pool` until a stopping rule fires (`placement_search`
    with one placement)."""
    return placement_search(args, reward, pool, progress, run_dir)[0]


def placement_search(args: SearchArgs, reward: Reward, pool: RolloutPool, progress: bool = True,
                     run_dir: Path | None = None, placements: list[EpisodeConditions] | None = None,
                     init_mu: np.ndarray | None = None, neighbours: int = 4,
                     lead_in: np.ndarray | None = None) -> list[SearchResult]:
    """Runs TTR at several bag placements at once (one table per placement, all rollouts in the same
    batches); None: the default placement only. Each placement's search may start from `init_mu` (a best
    trajectory found elsewhere, [decisions, A], or one per placement: a warm start), and from the second iteration on one of its rollouts is the
    best so far of one of its `neighbours` nearest placements, so what one placement finds spreads to the
    others. Stops when no placement improved for `plateau_iterations`. `lead_in` ([L, A], or [placements, L, A]):
    raw actions every rollout plays first, unrecorded, so that the search starts where they leave the character
    (a stance's guard: the server's `stance_guard_actions` held); None: the square guard at rest.

    With `run_dir` it checkpoints after every iteration and first continues from the checkpoint it finds
    there: the tables, the bests and the sampler's state, so a resumed search ends exactly where an
    uninterrupted one would."""
    rng = np.random.default_rng(args.seed)
    names = pool.info.feature_names
    clip_epsilon = args.clip_epsilon if args.clip_epsilon is not None else reward.search_clip_epsilon
    decisions = reward.frames // args.decision_period
    action_size = pool.info.action_size
    # A style narrows the search around the guard for the degrees of freedom a punch moves least (reward/style.py).
    sigma_cap = reward.style.search_sigma_cap(action_size) if reward.style is not None else None
    count = 1 if placements is None else len(placements)
    scale = np.ptp([p.position_m() for p in placements], axis=0) + 1e-6 if placements else np.ones(3)
    near = [np.argsort([np.linalg.norm((q.position_m() - p.position_m()) / scale) for q in placements])[1:neighbours + 1]
            for p in placements] if placements else [np.array([], dtype=int)]

    def returns_of(actions: np.ndarray, per_placement: int) -> tuple[np.ndarray, Terms, np.ndarray, np.ndarray]:
        bags = None if placements is None else [bag for bag in placements for _ in range(per_placement)]
        starts = None
        if lead_in is not None:
            per_start = np.broadcast_to(lead_in, (count, *np.shape(lead_in)[-2:]))
            starts = np.repeat(per_start, per_placement, axis=0).astype(np.float32)
        features, executed = pool.run(actions.reshape(-1, decisions, action_size), args.smoothing_window, bags, starts)
        returns, terms = score_terms(reward, features, names)
        return returns.reshape(count, per_placement), terms, features, executed

    def best_of(index: int, samples: np.ndarray, returns: np.ndarray, terms: Terms, features: np.ndarray,
                executed: np.ndarray, history: list[dict[str, Any]]) -> SearchResult:
        return SearchResult(samples.reshape(-1, decisions, action_size)[index].copy(), executed[index],
                            float(returns.reshape(-1)[index]), features[index],
                            {k: float(v[index].sum()) for k, v in terms.items()}, history, names,
                            best_slot=index % pool.characters_per_process)

    saved = load_checkpoint(run_dir, "search") if run_dir is not None else None
    if saved is None:
        start_mu = np.zeros((decisions, action_size), dtype=np.float32) if init_mu is None else np.asarray(init_mu, dtype=np.float32)
        mu = np.broadcast_to(start_mu, (count, decisions, action_size)).copy()
        sigma = np.full((count, decisions, action_size), args.sigma_init, dtype=np.float64)
        if sigma_cap is not None:
            sigma = np.minimum(sigma, sigma_cap)
        returns, terms, features, executed = returns_of(mu, 1)
        history: list[dict[str, Any]] = []
        bests = [best_of(p, mu, returns, terms, features, executed, history) for p in range(count)]
        done_iterations, rollouts_done, last_improvement, elapsed_before, stopped = 0, count, 0, 0.0, False
    else:
        mu, sigma, bests, history, (done_iterations, rollouts_done, last_improvement, elapsed_before, stopped) = restore_search(
            saved, args, rng, (count, decisions, action_size), len(names), names, pool.characters_per_process)
    if stopped:
        return bests

    start = time.perf_counter() - elapsed_before
    label = f"search {reward.name}" + (f" x {count} placements" if count > 1 else "")
    bar = tqdm(range(done_iterations + 1, args.iterations + 1), desc=label, unit="it",
               initial=done_iterations, total=args.iterations, disable=not progress)
    for iteration in bar:
        noise = rng.standard_normal((count, args.rollouts, decisions, action_size))
        samples = np.clip(mu[:, None] + sigma[:, None] * noise, -1.0, 1.0).astype(np.float32)
        if count > 1 and neighbours > 0 and iteration > 1:
            for p in range(count):
                samples[p, 0] = bests[int(rng.choice(near[p]))].best_actions
        returns, terms, features, executed = returns_of(samples, args.rollouts)
        rollouts_done += samples.shape[0] * samples.shape[1]
        for p in range(count):
            top = int(np.argmax(returns[p]))
            if returns[p, top] > bests[p].best_return:
                mu[p] = samples[p, top]
                bests[p] = best_of(p * args.rollouts + top, samples, returns, terms, features, executed, history)
                last_improvement = iteration
            sigma[p] = update_sigma(samples[p], returns[p], mu[p], bests[p].best_return, sigma[p], clip_epsilon, args.sigma_min)
            if sigma_cap is not None:
                sigma[p] = np.minimum(sigma[p], sigma_cap)
        elapsed = time.perf_counter() - start
        best_returns = np.array([b.best_return for b in bests])
        history.append({
            "iteration": iteration, "rollouts": rollouts_done, "elapsed_s": round(elapsed, 4),
            "best_return": float(best_returns.mean()), "mean_return": float(returns.mean()), "sigma_mean": float(sigma.mean()),
            **({f"best_{k}": v for k, v in bests[0].best_terms.items()} if count == 1 else {"worst_best_return": float(best_returns.min())}),
        })
        bar.set_postfix(best=f"{best_returns.mean():.3f}", rollouts_per_s=f"{rollouts_done / elapsed:.0f}")
        stopped = (iteration == args.iterations
                   or bool(args.plateau_iterations and iteration - last_improvement >= args.plateau_iterations)
                   or (args.time_budget_s is not None and elapsed >= args.time_budget_s))
        if run_dir is not None:
            save_checkpoint(run_dir, "search", {
                "iteration": iteration, "mu": mu, "sigma": sigma, "rng_state": rng.bit_generator.state,
                "bests": [{"actions": b.best_actions, "executed": b.best_executed, "return": b.best_return, "features": b.best_features,
                           "terms": b.best_terms, "slot": b.best_slot} for b in bests],
                "history": history, "rollouts": rollouts_done, "last_improvement": last_improvement,
                "elapsed_s": elapsed, "stopped": stopped})
        if stopped:
            break
    bar.close()
    return bests
