"""`punch train`: the whole pipeline for one reward. Trajectory search, then the dataset, supervised
pretraining, A2C, and export to ONNX, ending with a noise-free run of the exported policy in the
simulator. Everything goes into one run directory with a short report."""

from __future__ import annotations

import csv
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnxruntime

from punch_trainer.cli.search import run_search
from punch_trainer.learn.a2c import A2CArgs, evaluate_noise_free, train_a2c
from punch_trainer.learn.checkpoint import CONFIG_FILE, CheckpointError, default_run_dir, load_checkpoint, save_checkpoint, write_config
from punch_trainer.learn.dataset import load_datasets
from punch_trainer.learn.export import export_policy
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.pretrain import PretrainArgs, pretrain
from punch_trainer.learn.search import SearchArgs
from punch_trainer.report.motion import motion_report
from punch_trainer.sim.env import PunchVectorEnv
from punch_trainer.sim.rewards import Reward, load_reward, score


@dataclass
class TrainArgs:
    reward: str = "straight"
    frames: int | None = None
    seed: int = 0
    out: Path | None = None
    search_iterations: int = 100
    search_rollouts: int = 64
    smoothing_window: int = 3
    pretrain_epochs: int = 1500
    a2c_updates: int = 40
    a2c_characters: int = 32
    advantage: str = "gae"
    a2c_time_budget_s: float | None = 60.0
    """stop A2C after this much wall time (None or 0: no limit, which makes a run reproducible)"""

    def run_dir(self) -> Path:
        """`out`, or a new runs/train_<reward>__<seed>__<time>."""
        return self.out or default_run_dir(f"train_{self.reward}", self.seed)


def run_exported_policy(path: Path, env: PunchVectorEnv, reward: Reward, sigma: float = 0.0,
                        seed: int = 0) -> tuple[float, np.ndarray]:
    """Runs an exported policy file with onnxruntime in the simulator (noise `sigma` on its mean); returns
    character 0's return and its features [frames, F]."""
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(seed)
    obs, _ = env.reset()
    total_return, frames = 0.0, []
    while True:
        mean, _ = session.run(None, {"obs": obs.astype(np.float32)})
        action = np.clip(mean + sigma * rng.standard_normal(mean.shape), -1, 1).astype(np.float32)
        obs, _, terminated, truncated, info = env.step(action)
        total_return += float(score(reward, info["features"][:1], env.feature_names)[0])
        frames.append(info["features"][0])
        if terminated[0] or truncated[0]:
            return total_return, np.concatenate(frames)


def run_train(args: TrainArgs, progress: bool = True, resume: bool = False) -> Path:
    """The whole `punch train` command. Every stage checkpoints in its own folder of the run directory
    (search/, pretrain/, a2c/); `resume` continues the run in `args.out` from them."""
    started = time.perf_counter()
    reward = load_reward(args.reward, args.frames)
    out = args.run_dir()
    if not resume and (out / CONFIG_FILE).exists():
        raise CheckpointError(f"{out} already holds a training run; continue it with `punch train --resume {out}` or choose another --out")
    write_config(out, args)
    timings = {}

    search_args = SearchArgs(reward=args.reward, frames=reward.frames, seed=args.seed, out=out / "search",
                             iterations=args.search_iterations, rollouts=args.search_rollouts,
                             characters_per_process=min(64, args.search_rollouts), smoothing_window=args.smoothing_window)
    _, search, _ = run_search(search_args, progress, resume=resume)
    timings["search_s"] = time.perf_counter() - started

    data = load_datasets([out / "search" / "dataset.npz"])
    model = ActorCritic(data["observations"].shape[1], data["actions"].shape[1], seed=args.seed)
    pretrained = load_checkpoint(out / "pretrain", "pretrain") if resume else None
    if pretrained is None:
        pretrain_history = pretrain(model, data, PretrainArgs(epochs=args.pretrain_epochs, seed=args.seed), progress)
        save_checkpoint(out / "pretrain", "pretrain", {"model": model.state_dict(), "history": pretrain_history})
    else:
        model.load_state_dict(pretrained["model"])
        pretrain_history = pretrained["history"]
    timings["pretrain_s"] = time.perf_counter() - started - timings["search_s"]

    env = PunchVectorEnv(1, args.a2c_characters, frames=reward.frames, smoothing_window=args.smoothing_window)
    try:
        pretrained_return = evaluate_noise_free(model, env, reward)
        a2c_args = A2CArgs(updates=args.a2c_updates, characters=args.a2c_characters, advantage=args.advantage,
                           smoothing_window=args.smoothing_window, time_budget_s=args.a2c_time_budget_s or None, seed=args.seed)
        model, a2c_history = train_a2c(model, reward, a2c_args, env, progress, run_dir=out / "a2c",
                                       start_rollouts=search.history[-1]["rollouts"] if search.history else 0)
        timings["a2c_s"] = time.perf_counter() - started - timings["search_s"] - timings["pretrain_s"]

        summary = {"search_best_return": search.best_return, "pretrained_return": pretrained_return,
                   "a2c_best_eval_return": max(h["eval_return"] for h in a2c_history), "a2c_updates": len(a2c_history) - 1}
        policy_path = export_policy(model, out / "policy.onnx", contract=data["policy_metadata"], reward=reward.name, summary=summary)
        exported_return, features = run_exported_policy(policy_path, env, reward)
    finally:
        env.close()
    timings["total_s"] = time.perf_counter() - started

    with open(out / "a2c_metrics.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(a2c_history[0]))
        writer.writeheader()
        writer.writerows(a2c_history)
    ratio = exported_return / search.best_return if search.best_return > 0 else float("nan")
    motion = motion_report({"features": features, "feature_names": np.array(env.feature_names), "physics_hz": np.array(env.info.physics_hz)})
    impact = (f"first contact at {motion['impact_time_s']:.3f} s at {motion['impact_speed_mps']:.2f} m/s, contact point "
              f"{motion['contact_point_from_bag_centre_m']} m from the bag's centre" if motion["impact_time_s"] is not None
              else "no contact with the bag")
    lines = [
        f"# punch train: {reward.name}", "",
        f"- trajectory search: best return {search.best_return:.4f} ({search_args.iterations} iterations of {search_args.rollouts} rollouts)",
        f"- after pretraining ({args.pretrain_epochs} epochs, final actor MSE {pretrain_history[-1]['actor_mse']:.2e}): noise-free return {pretrained_return:.4f}",
        f"- after A2C ({len(a2c_history) - 1} updates x {args.a2c_characters} episodes, advantage '{args.advantage}'): "
        f"best noise-free return {max(h['eval_return'] for h in a2c_history):.4f}",
        f"- exported policy (onnxruntime, sigma 0) in the simulator: return {exported_return:.4f} = {100 * ratio:.1f}% of the search's best",
        f"- the exported policy's punch: peak right-fist speed {motion['peak_fist_speed_mps']:.2f} m/s; {impact}",
        f"- timings: search {timings['search_s']:.1f} s, pretraining {timings['pretrain_s']:.1f} s, A2C {timings['a2c_s']:.1f} s, "
        f"total {timings['total_s']:.1f} s",
        f"- policy: `policy.onnx` (input `obs` [B, {env.info.observation_size}], outputs `mean`, `sigma` [B, {env.info.action_size}]; "
        f"metadata: spec hash {data['policy_metadata']['punch_spec_hash']})",
        "", "Search details: [search/report.md](search/report.md)",
    ]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "summary.json").write_text(json.dumps({"search_best_return": search.best_return, "pretrained_return": pretrained_return,
                                                  "exported_return": exported_return, "ratio": ratio, "motion": motion, **timings}, indent=2) + "\n")
    return out

