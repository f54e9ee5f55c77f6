"""The paper's Fig. 6 experiment, extended: mean episode return against episodes, environment steps and
wall time for
- A2C alone, from a fresh network;
- A2C after pretraining on the trajectory search's best trajectory, with the standard advantage (GAE) and
  with the paper's advantage as printed;
- Stable-Baselines3 PPO with small n_steps, on the same Gymnasium env, as an outside baseline.

Environment steps count agent decisions per character. The pretrained variants start their counts, their
episodes and their clocks after the search's own rollouts, so their x-axes are honest.

And `after_punch_headroom` (`punch experiment after-punch`): what a punch that starts from the end of an earlier
one can score at all, against one from the guard, found by the same search.
"""

from __future__ import annotations

import csv
import functools
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.learn.a2c import A2CArgs, train_a2c
from punch_trainer.learn.dataset import record_dataset, returns_to_go
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.pretrain import PretrainArgs, pretrain
from punch_trainer.learn.search import SearchArgs, trajectory_search
from punch_trainer.reward.rewards import Reward, load_reward
from punch_trainer.sim.conditions import EpisodeConditions, EpisodeStart
from punch_trainer.sim.env import PunchEnv, PunchVectorEnv
from punch_trainer.sim.rollouts import RolloutPool
from punch_trainer.sim.server_group import SimulatorRestarts

METHODS = ["A2C only", "A2C after pretraining (GAE)", "A2C after pretraining (paper's advantage)", "SB3 PPO"]


@dataclass
class Fig6Args:
    """The options of `punch experiment fig6`."""

    reward: str = "straight"
    """a preset (the paper's straight, straight100, hook and swing, and the moves' rewards: README, "Training your own
    punch") or FILE.py:FUNCTION"""
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    """one run of every method per seed"""
    search_iterations: int = 60
    """iterations of the trajectory search (64 rollouts each) before the pretrained variants"""
    a2c_updates: int = 40
    """A2C updates of the pretrained variants (A2C alone and PPO get as many environment steps in all)"""
    characters: int = 32
    """characters simulated at once: A2C's episodes per update, and PPO's window of episodes for its mean return"""


@dataclass
class AfterPunchArgs:
    """The options of `punch experiment after-punch`."""

    dataset: Path
    """a search's dataset.npz: its best punch is the earlier one"""
    iterations: int = 40
    """iterations of the cross-entropy search from each start"""
    rollouts: int = 64
    """rollouts per iteration"""
    seed: int = 0
    """seed of the search"""


@dataclass(frozen=True)
class Fig6Result:
    """One method's figures, averaged over the seeds (`fig6`)."""

    method: str
    final_mean_return: float
    """the mean return of the sampled (noisy) episodes at the end of the run, mean over seeds"""
    final_mean_return_sd: float
    """its standard deviation over seeds"""
    best_noise_free_return: float
    """the best return of the policy's mean actions over the run, mean over seeds (NaN for PPO: not evaluated)"""
    env_steps: int
    wall_s: float


@dataclass(frozen=True)
class AfterPunchHeadroom:
    """What the search found from one start (`after_punch_headroom`)."""

    start: str
    """where the punch starts: the guard, or the end of the best punch"""
    best_return: float
    last_batch_hit_share: float
    """the share of the last batch that hit (a positive return and the right fist touched the bag)"""


def _a2c_curve(history: list[dict[str, Any]], offset_steps: int, offset_episodes: int, offset_s: float) -> list[dict[str, Any]]:
    return [{"episodes": h["episodes"] + offset_episodes, "env_steps": h["env_steps"] + (offset_steps if h["update"] else 0),
             "wall_s": h["elapsed_s"] + offset_s, "mean_return": h["mean_return"], "eval_return": h["eval_return"]}
            for h in history if h["update"] > 0]


def _ppo_curve(reward: Reward, seed: int, total_steps: int, frames: int, smoothing_window: int, window: int) -> list[dict[str, Any]]:
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    class Episodes(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.start = time.perf_counter()
            self.returns: list[float] = []
            self.rows: list[dict[str, Any]] = []

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    self.returns.append(float(info["episode"]["r"]))
                    recent = self.returns[-window:]
                    self.rows.append({"episodes": len(self.returns), "env_steps": self.num_timesteps,
                                      "wall_s": time.perf_counter() - self.start, "mean_return": float(np.mean(recent)),
                                      "eval_return": float("nan")})
            return True

    env = PunchEnv(frames=frames, smoothing_window=smoothing_window, reward=reward)
    from stable_baselines3.common.monitor import Monitor

    callback = Episodes()
    try:
        model = PPO("MlpPolicy", Monitor(env), n_steps=128, batch_size=64, seed=seed, verbose=0, device="cpu")
        model.learn(total_timesteps=total_steps, callback=callback)
    finally:
        env.close()
    return callback.rows


def fig6(args: Fig6Args, smoothing_window: int = 3, out: Path | None = None) -> tuple[Path, list[Fig6Result]]:
    reward_name, seeds, search_iterations = args.reward, args.seeds, args.search_iterations
    a2c_updates, characters = args.a2c_updates, args.characters
    reward = load_reward(reward_name)
    out = out or Path("runs") / f"fig6_{reward.name}"
    out.mkdir(parents=True, exist_ok=True)
    curves: Curves = {}
    jobs = [(method, seed) for seed in seeds for method in METHODS]
    progress = tqdm(jobs, desc="fig6", unit="run")
    with PunchVectorEnv(1, characters, frames=reward.frames, smoothing_window=smoothing_window) as env:
        decisions = reward.frames // env.info.decision_period
        sizes = (env.info.observation_size, env.info.action_size)
        # Matched budgets: A2C alone and PPO get as many environment steps as the pretrained variants use in
        # all, the search's rollouts (and its first evaluation of the zero sequence) included.
        matched_steps = (search_iterations * 64 + 1) * decisions + a2c_updates * characters * decisions
        scratch_updates = -(-matched_steps // (characters * decisions))
        for method, seed in progress:
            a2c_args = A2CArgs(updates=a2c_updates, characters=characters, smoothing_window=smoothing_window, seed=seed,
                               advantage="paper" if "paper" in method else "gae")
            if method == "A2C only":
                model = ActorCritic(*sizes, seed=seed)  # identity normalisation: nothing is known before simulating
                a2c_args.updates = scratch_updates
                _, history = train_a2c(model, reward, a2c_args, env, progress=False)
                curves[(method, seed)] = _a2c_curve(history, 0, 0, 0.0)
            elif method.startswith("A2C after pretraining"):
                start = time.perf_counter()
                search_args = SearchArgs(reward=reward_name, seed=seed, iterations=search_iterations, rollouts=64,
                                         plateau_iterations=0, smoothing_window=smoothing_window)
                with RolloutPool(1, 64) as pool:
                    result = trajectory_search(search_args, reward, pool, progress=False)
                dataset = record_dataset(result, reward, search_args)
                data = {"observations": dataset["observations"], "actions": dataset["actions"],
                        "rewards": dataset["rewards"], "returns_to_go": returns_to_go(dataset["rewards"], 1.0)}
                model = ActorCritic(*sizes, seed=seed)
                pretrain(model, data, PretrainArgs(epochs=1500, seed=seed), progress=False)
                search_rollouts = result.history[-1]["rollouts"]
                _, history = train_a2c(model, reward, a2c_args, env, progress=False)
                curves[(method, seed)] = _a2c_curve(history, search_rollouts * decisions, search_rollouts, time.perf_counter() - start - history[-1]["elapsed_s"])
            else:
                curves[(method, seed)] = _ppo_curve(reward, seed, matched_steps, reward.frames, smoothing_window, characters)
    rows = _summarise(curves, seeds)
    _write(out, curves, reward)
    return out, rows


Curves = dict[tuple[str, int], list[dict[str, Any]]]
"""(method, seed) -> the points of its learning curve"""


def _summarise(curves: Curves, seeds: Sequence[int]) -> list[Fig6Result]:
    rows = []
    for method in METHODS:
        finals = [curves[(method, s)][-1] for s in seeds if curves.get((method, s))]
        rows.append(Fig6Result(
            method=method,
            final_mean_return=float(np.mean([f["mean_return"] for f in finals])),
            final_mean_return_sd=float(np.std([f["mean_return"] for f in finals])),
            best_noise_free_return=float(np.nanmean([max(r["eval_return"] for r in curves[(method, s)]) for s in seeds])) if "PPO" not in method else float("nan"),
            env_steps=int(np.mean([f["env_steps"] for f in finals])),
            wall_s=float(np.mean([f["wall_s"] for f in finals])),
        ))
    return rows


def _write(out: Path, curves: Curves, reward: Reward) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(out / "curves.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["method", "seed", "episodes", "env_steps", "wall_s", "mean_return", "eval_return"])
        for (method, seed), curve in curves.items():
            for point in curve:
                writer.writerow([method, seed, point["episodes"], point["env_steps"], round(point["wall_s"], 3), point["mean_return"], point["eval_return"]])
    figure, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    colors = dict(zip(METHODS, ["tab:blue", "tab:red", "tab:orange", "tab:green"]))
    for (method, seed), curve in curves.items():
        for axis, key in zip(axes, ["episodes", "env_steps", "wall_s"]):
            axis.plot([p[key] for p in curve], [p["mean_return"] for p in curve], color=colors[method], alpha=0.7,
                      label=method if seed == min(s for m, s in curves if m == method) else None)
    for axis, label in zip(axes, ["episodes", "environment steps (decisions; search rollouts included)", "wall time (s)"]):
        axis.set_xlabel(label)
        axis.set_ylabel("mean episode return")
        axis.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    figure.suptitle(f"Policy learning for '{reward.name}' (paper Fig. 6): mean return of the sampled episodes")
    figure.tight_layout()
    figure.savefig(out / "fig6.png", dpi=90)
    plt.close(figure)


def fig6_table(rows: list[Fig6Result]) -> str:
    lines = ["| method | final mean episode return (mean +- sd over seeds) | best noise-free return | env steps | wall time (s) |",
             "|---|---|---|---|---|"]
    for r in rows:
        best = "-" if np.isnan(r.best_noise_free_return) else f"{r.best_noise_free_return:.3f}"
        lines.append(f"| {r.method} | {r.final_mean_return:.3f} +- {r.final_mean_return_sd:.3f} | {best} | {r.env_steps:,} | {r.wall_s:.1f} |")
    return "\n".join(lines)


def after_punch_headroom(args: AfterPunchArgs, elites: int = 8) -> list[AfterPunchHeadroom]:
    """How much a punch can score when it starts from the end of an earlier one, against one from the guard.

    An open-loop cross-entropy search (the same for both starts, so the two are comparable) through the env, at
    the dataset's bag placement, with its frames and smoothing window; the earlier punch is the dataset's best
    (its executed actions, replayed as a lead-in). Returns one row per start: the best return found and the share
    of the last batch that hit (a positive return and the right fist touched the bag)."""
    from punch_trainer.learn.volume import success

    dataset_path, iterations, rollouts, seed = args.dataset, args.iterations, args.rollouts, args.seed
    with np.load(dataset_path) as data:
        earlier = data["executed_actions"].astype(np.float32)
        bag = EpisodeConditions.from_wire(json.loads(str(data["bag"])))
        reward = load_reward(str(data["reward"]), int(data["frames"]))
        frames, period, window = int(data["frames"]), int(data["decision_period"]), int(data["smoothing_window"])
    decisions, action_size = earlier.shape
    rng = np.random.default_rng(seed)
    rows = []
    with PunchVectorEnv(1, rollouts, frames=frames, decision_period=period, smoothing_window=window, reward=reward) as env:
        restarts = SimulatorRestarts(env.restart)

        def batch(actions: np.ndarray, lead_in: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
            env.reset(options=EpisodeStart([bag] * rollouts, lead_in))
            returns, features = np.zeros(rollouts), []
            for decision in range(decisions):
                _, rewards, _, _, info = env.step(actions[:, decision])
                returns += rewards
                features.append(info["features"])
            return returns, np.concatenate(features, axis=1)

        for start, lead_in in [("the guard", None), ("the end of the best punch", np.repeat(earlier[None], rollouts, axis=0))]:
            mean, sigma, best = np.zeros((decisions, action_size)), np.full((decisions, action_size), 0.6), -np.inf
            for _ in tqdm(range(iterations), desc=f"from {start}", leave=False):
                actions = np.clip(mean + sigma * rng.standard_normal((rollouts, decisions, action_size)), -1, 1).astype(np.float32)
                actions[0] = np.clip(mean, -1, 1)  # the current mean is always tried
                returns, features = restarts.run(functools.partial(batch, actions, lead_in))
                hit = success(returns, features, env.feature_names)
                elite = actions[np.argsort(returns)[-elites:]]
                mean, sigma = elite.mean(axis=0), np.maximum(elite.std(axis=0), 0.05)
                best = max(best, float(returns.max()))
            rows.append(AfterPunchHeadroom(start=start, best_return=best, last_batch_hit_share=float(hit.mean())))
    return rows
