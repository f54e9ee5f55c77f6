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

import csv
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from punch_trainer import __version__
from punch_trainer.checkpoint import CHECKPOINT_FILE, CheckpointError, default_run_dir, load_checkpoint, save_checkpoint, write_config
from punch_trainer.rewards import Reward, evaluate, load_reward, total
from punch_trainer.rollouts import RolloutPool
from punch_trainer.server import TrainingServer

DOF_COUNT = 10


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
    history: list[dict] = field(default_factory=list)
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
    return np.maximum(np.clip(spread, (1 - clip_epsilon) * sigma, (1 + clip_epsilon) * sigma), sigma_min)


def evaluate_actions(pool: RolloutPool, reward: Reward, actions: np.ndarray, smoothing_window: int):
    """Runs raw action sequences [M, decisions, 10] and scores them: (returns [M], per-frame terms,
    features [M, frames, F], executed actions [M, decisions, 10])."""
    features, executed = pool.run(actions, smoothing_window)
    terms = evaluate(reward, features, pool.info.feature_names)
    return total(terms).sum(axis=-1), terms, features, executed


def trajectory_search(args: SearchArgs, reward: Reward, pool: RolloutPool, progress: bool = True,
                      run_dir: Path | None = None) -> SearchResult:
    """Runs TTR on `pool` until a stopping rule fires. With `run_dir` it checkpoints after every iteration
    and first continues from the checkpoint it finds there: mu, sigma, the best so far and the sampler's
    state, so a resumed search ends exactly where an uninterrupted one would."""
    rng = np.random.default_rng(args.seed)
    names = pool.info.feature_names
    clip_epsilon = args.clip_epsilon if args.clip_epsilon is not None else reward.search_clip_epsilon
    decisions = reward.frames // args.decision_period

    def returns_of(actions: np.ndarray):
        return evaluate_actions(pool, reward, actions, args.smoothing_window)

    saved = load_checkpoint(run_dir, "search") if run_dir is not None else None
    if saved is None:
        mu = np.zeros((decisions, DOF_COUNT), dtype=np.float32)
        sigma = np.full((decisions, DOF_COUNT), args.sigma_init, dtype=np.float64)
        returns, terms, features, executed = returns_of(mu[None])
        best = SearchResult(mu.copy(), executed[0], float(returns[0]), features[0],
                            {k: float(v[0].sum()) for k, v in terms.items()}, feature_names=names)
        done_iterations, rollouts_done, last_improvement, elapsed_before, stopped = 0, 1, 0, 0.0, False
    else:
        mu, sigma = saved["mu"].numpy(), saved["sigma"].numpy()
        if mu.shape != (decisions, DOF_COUNT):
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
        samples = np.clip(mu + sigma * rng.standard_normal((args.rollouts, decisions, DOF_COUNT)), -1.0, 1.0).astype(np.float32)
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


def replay_dataset(result: SearchResult, reward: Reward, args: SearchArgs) -> dict[str, np.ndarray]:
    """Replays the best trajectory one step per decision, in the same slot of a server of the same size as
    the search's (so that it is bitwise the same trajectory: docs/env.md, Episodes), and stores per decision
    the observation seen, the raw and executed action and the reward, plus every frame's features. The
    replay must reproduce the search's features exactly."""
    slot, slot_count = result.best_slot, args.characters_per_process
    with TrainingServer(slot_count, decision_period=args.decision_period) as server:
        reply = server.reset(reward.frames, smoothing_window=args.smoothing_window)
        observations, executed, frames = [reply.arrays["observations"][slot]], [], []
        for action in result.best_actions:
            actions = np.zeros((slot_count, DOF_COUNT), dtype=np.float32)
            actions[slot] = action
            step = server.step(actions)
            observations.append(step.arrays["observations"][slot])
            executed.append(step.arrays["executed_actions"][slot, 0])
            frames.append(step.arrays["features"][slot])
        info = server.info
    features = np.concatenate(frames)
    per_frame = total(evaluate(reward, features, info.feature_names))
    rewards = per_frame.reshape(len(result.best_actions), args.decision_period).sum(axis=1)
    if not np.array_equal(features, result.best_features):
        raise RuntimeError("replaying the best trajectory did not reproduce its features; the physics is not deterministic")
    return {
        "observations": np.stack(observations[:-1]).astype(np.float32),
        "next_observations": np.stack(observations[1:]).astype(np.float32),
        "actions": result.best_actions.astype(np.float32),
        "executed_actions": np.stack(executed).astype(np.float32),
        "rewards": rewards.astype(np.float32),
        "features": features.astype(np.float32),
        "feature_names": np.array(info.feature_names),
        "observation_names": np.array(info.observation_names),
        "spec_hash": np.array(info.spec_hash),
        "reward": np.array(reward.name),
        "frames": np.array(reward.frames),
        "decision_period": np.array(args.decision_period),
        "smoothing_window": np.array(args.smoothing_window),
        "physics_hz": np.array(info.physics_hz),
        "return": np.array(float(per_frame.sum())),
    }


CONTACT_IMPULSE_NS = 1e-3
"""A right-fist impulse on the bag above this (N s) counts as contact."""


def first_right_contact(features: np.ndarray, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Of features [..., frames, F]: whether the right fist touched the bag, and the first frame it did (0 if never)."""
    col = names.index
    impulse = np.linalg.norm(features[..., col("fist_r_impulse_x"):col("fist_r_impulse_z") + 1], axis=-1)
    touched = impulse > CONTACT_IMPULSE_NS
    return touched.any(axis=-1), touched.argmax(axis=-1)


def motion_report(dataset: dict[str, np.ndarray]) -> dict[str, float | list[float] | None]:
    """Peak fist speed, time to impact and contact point (relative to the bag's centre) of a trajectory."""
    names = [str(n) for n in dataset["feature_names"]]
    f = dataset["features"]
    col = names.index
    velocity = f[:, col("fist_r_vel_x"):col("fist_r_vel_z") + 1]
    speed = np.linalg.norm(velocity, axis=1)
    hit, first = first_right_contact(f, names)
    hz = float(dataset["physics_hz"])
    report: dict[str, float | list[float] | None] = {
        "peak_fist_speed_mps": float(speed.max()),
        "peak_fist_speed_time_s": float((speed.argmax() + 1) / hz),
        "closest_fist_bag_distance_m": float(f[:, col("fist_r_bag_distance")].min()),
        "impact_time_s": None, "impact_speed_mps": None, "contact_point_from_bag_centre_m": None,
    }
    if hit:
        first = int(first)
        fist = f[first, col("fist_r_pos_x"):col("fist_r_pos_z") + 1]
        bag = f[first, col("bag_pos_x"):col("bag_pos_z") + 1]
        report.update(impact_time_s=(first + 1) / hz, impact_speed_mps=float(speed[max(first - 1, 0)]),
                      contact_point_from_bag_centre_m=[round(float(v), 4) for v in fist - bag])
    return report


def write_run(out: Path, args: SearchArgs, reward: Reward, result: SearchResult, dataset: dict, report: dict, info) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_config(out, args, frames=reward.frames, punch_version=__version__, spec_hash=info.spec_hash,
                 extension_version=info.extension_version,
                 clip_epsilon=args.clip_epsilon if args.clip_epsilon is not None else reward.search_clip_epsilon)
    with open(out / "metrics.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(result.history[0]) if result.history else ["iteration"])
        writer.writeheader()
        writer.writerows(result.history)
    np.savez_compressed(out / "dataset.npz", **dataset)
    from punch_trainer.plots import plot_search

    plots = plot_search(out, result, dataset)
    from punch_trainer.mocap import DEFAULT_BVH, captured_punch, plot_against_capture

    capture_plot = plot_against_capture(out, dataset)
    if capture_plot is not None:
        plots.append(capture_plot)
        report["captured_punch_peak_speed_mps"] = float(captured_punch(DEFAULT_BVH)["peak_speed_mps"])
    lines = [
        f"# Trajectory search: {reward.name}", "",
        f"- best return: {result.best_return:.4f} ({', '.join(f'{k} {v:.4f}' for k, v in result.best_terms.items())})",
        f"- iterations: {len(result.history)}, rollouts: {result.history[-1]['rollouts'] if result.history else 1}, "
        f"wall time: {result.history[-1]['elapsed_s'] if result.history else 0:.1f} s",
        f"- episode: {reward.frames} frames at {info.physics_hz} Hz = {reward.frames / info.physics_hz:.2f} s, "
        f"{reward.frames // args.decision_period} decisions, smoothing window {args.smoothing_window}",
        f"- peak right-fist speed: {report['peak_fist_speed_mps']:.2f} m/s at {report['peak_fist_speed_time_s']:.3f} s",
    ]
    if report["impact_time_s"] is not None:
        lines.append(f"- first contact with the bag: {report['impact_time_s']:.3f} s at {report['impact_speed_mps']:.2f} m/s; "
                     f"contact point relative to the bag's centre (x left, y up, z away): {report['contact_point_from_bag_centre_m']} m")
    else:
        lines.append(f"- no contact with the bag (closest distance {report['closest_fist_bag_distance_m']:.3f} m)")
    if "captured_punch_peak_speed_mps" in report:
        lines.append(f"- captured punch (CMU 143/23, scaled to this arm): peak hand speed {report['captured_punch_peak_speed_mps']:.2f} m/s; "
                     "fist_vs_capture.png compares the paths, aligned at the shoulder")
    lines += ["", "## Plots", ""] + [f"![{p.stem}]({p.name})" for p in plots]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "motion.json").write_text(json.dumps(report, indent=2) + "\n")


def run_search(args: SearchArgs, progress: bool = True, resume: bool = False) -> tuple[Path, SearchResult, dict]:
    """The whole `punch search` command: search, dataset, run directory. `resume` continues the run in
    `args.out` from its checkpoint (the CLI reads its arguments back with `checkpoint.read_config`)."""
    reward = load_reward(args.reward, args.frames)
    if reward.frames % args.decision_period:
        raise ValueError(f"frames ({reward.frames}) must be a multiple of the decision period ({args.decision_period})")
    out = args.run_dir()
    if not resume and (out / CHECKPOINT_FILE).exists():
        raise CheckpointError(f"{out} already holds a search; continue it with `punch search --resume {out}` or choose another --out")
    write_config(out, args, frames=reward.frames)  # first, so that an interrupted run can be resumed
    with RolloutPool(args.processes, args.characters_per_process, decision_period=args.decision_period) as pool:
        result = trajectory_search(args, reward, pool, progress, run_dir=out)
        info = pool.info
    dataset = replay_dataset(result, reward, args)
    report = motion_report(dataset)
    write_run(out, args, reward, result, dataset, report, info)
    return out, result, report

