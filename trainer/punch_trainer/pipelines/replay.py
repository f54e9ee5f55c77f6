"""Replay experiment (the paper's Fig. 10-11): how a trained policy's punches vary with the runtime noise sigma.

The punches run in headless Godot through `PunchController` itself (godot_project/tools/evaluate.gd, the evaluator's driver), the same
node, ONNX Runtime call and noise a game uses; not the torch policy. Godot writes what every punch did, and
this module scores it with the policy's reward (named in its metadata) and reports per sigma:

- return ratio: mean return / the trajectory search's best return (from the policy's training summary),
- success rate: the share of punches with a return > 0,
- spread of the impact points (first contact of the right fist) and of the right fist's paths (m).

    punch replay --policy runs/NAME/policy.onnx --sigmas 0.1:0.9:0.1 --episodes 10000 [--noise-decisions 4]
"""

from __future__ import annotations

import json
import math
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.pipelines.evaluation import KINDS, EvalError, analyse_punches, recorded, run_episodes
from punch_trainer.policy_file import PolicyMetadata, read_entries, read_policy_metadata
from punch_trainer.reward.rewards import metadata_reward


class ReplayError(EvalError):
    """The replay could not run: a bad policy file, bad arguments, or Godot failed."""


@dataclass
class ReplayArgs:
    policy: Path
    """the exported policy (runs/NAME/policy.onnx)"""
    sigmas: list[float] = field(default_factory=lambda: [round(0.1 * i, 1) for i in range(1, 10)])
    """runtime noise sigmas to replay (start:stop:step, inclusive, or a,b,c)"""
    episodes: int = 1000
    """punches per sigma"""
    noise_decisions: int = -1
    """noise on the first k decisions only (-1: every decision; the paper's "Noise < 4" is 4)"""
    reward: str | None = None
    """reward to score with (default: the one the policy was trained for, from its metadata)"""
    characters: int = 64
    """characters punching at once in Godot"""
    characters_per_world: int = 16
    """characters sharing one physics world (1: each its own)"""
    seed: int = 0
    """noise seed"""
    out: Path | None = None
    """output directory (default: next to the policy, replay_<time>)"""
    keep_frames: bool = False
    """keep Godot's raw per-frame files (large: 11 kB per punch)"""
    timeout_s: float = 3600.0
    """how long Godot may take for the whole replay"""


def training_best_return(metadata: PolicyMetadata, source: str) -> float | None:
    """The search's best return from a policy's training summary (None when it has none), checked before Godot
    runs: a finite number (the summary itself is checked by `PolicyMetadata`)."""
    best = (metadata.training_summary or {}).get("search_best_return")
    if best is not None and (isinstance(best, bool) or not isinstance(best, (int, float)) or not math.isfinite(best)):
        raise ReplayError(f"{source}: its metadata's search_best_return {best!r} is not a finite number")
    return None if best is None else float(best)


def policy_metadata(path: Path) -> dict[str, str]:
    """Every metadata entry of the policy file `path`, as it holds them (`policy_file.read_entries`)."""
    return read_entries(path)


def replay_episodes(args: ReplayArgs) -> list[dict[str, Any]]:
    """evaluate.gd's episodes of a replay: `episodes` punches at the spec's default target for each sigma, episode
    e of sigma index s with noise seed seed * 1000003 + s * 100003 + e (the evaluator's rule)."""
    return [{"sigma": sigma, "noise_decisions": args.noise_decisions, "seed": args.seed * 1_000_003 + index * 100_003 + e}
            for index, sigma in enumerate(args.sigmas) for e in range(args.episodes)]


def run_godot_replay(args: ReplayArgs, frames_dir: Path, progress: bool = True, idle_frames: int = 0) -> dict[str, Any]:
    """Plays the replay's punches (`replay_episodes`) through the evaluator's Godot driver, recording them into
    `frames_dir`; returns its episodes.json. `idle_frames`: frames each batch stands idle after its punches (for
    `punch bench inference`)."""
    with tqdm(total=len(args.sigmas) * args.episodes, desc="replay (Godot)", unit="punch", disable=not progress) as bar:
        def advance(done: int) -> None:
            bar.update(done - bar.n)

        meta = run_episodes(args.policy, replay_episodes(args), frames_dir, record=True, characters=args.characters,
                            characters_per_world=args.characters_per_world, idle_frames=idle_frames,
                            timeout_s=args.timeout_s, on_progress=advance,
                            timeout_error=ReplayError)
    meta.update(sigmas=list(args.sigmas), episodes_per_sigma=args.episodes)
    (frames_dir / "meta.json").write_text(json.dumps(meta))
    return meta


def run_replay(args: ReplayArgs, progress: bool = True) -> tuple[Path, list[dict[str, Any]]]:
    metadata = read_policy_metadata(args.policy)
    if not args.sigmas or any(not 0.0 <= s <= 1.0 for s in args.sigmas):
        raise ReplayError(f"sigmas must lie in [0, 1], got {args.sigmas}")
    if args.episodes < 1:
        raise ReplayError("--episodes must be at least 1")
    reward = metadata_reward(metadata.entries, str(args.policy), args.reward)
    best = training_best_return(metadata, str(args.policy))
    out = Path(args.out or Path(args.policy).parent / f"replay_{int(time.time())}")
    frames_dir = out / "frames"
    created = not out.exists()
    frames_dir.mkdir(parents=True, exist_ok=True)

    started = time.perf_counter()
    try:
        meta = run_godot_replay(args, frames_dir, progress)
    except BaseException:
        if created:  # a replay that failed leaves no empty folder behind (by default, beside the policy)
            shutil.rmtree(out, ignore_errors=True)
        raise
    godot_s = time.perf_counter() - started
    names = [str(n) for n in meta["feature_names"]]
    rows, analyses = [], []
    for index, sigma in enumerate(args.sigmas):
        features = recorded(frames_dir, meta, "features", index * args.episodes, args.episodes)
        analysis = analyse_punches(features, names, reward)
        returns = analysis["returns"]
        rows.append({
            "sigma": sigma, "episodes": args.episodes, "mean_return": float(returns.mean()),
            "return_ratio": float(returns.mean() / best) if best else None,
            "success_rate": float((returns > 0).mean()), "hit_rate": analysis["hit_rate"],
            "impact_spread_m": analysis["impact_spread_m"], "path_spread_m": analysis["path_spread_m"],
        })
        analyses.append(analysis)
        del features
    if not args.keep_frames:
        for kind in KINDS:
            (frames_dir / f"{kind}.f32").unlink(missing_ok=True)

    from punch_trainer.report.plots import plot_replay

    plots = plot_replay(out, args.sigmas, rows, analyses, best)
    config = {"policy": str(args.policy), "reward": reward.name, "search_best_return": best, "noise_decisions": args.noise_decisions,
              "episodes": args.episodes, "seed": args.seed, "godot_s": round(godot_s, 1),
              "punches_per_s": round(len(args.sigmas) * args.episodes / godot_s, 1)}
    (out / "replay.json").write_text(json.dumps({"config": config, "rows": rows}, indent=2) + "\n")
    lines = [f"# punch replay: {Path(args.policy)}", "",
             f"Reward `{reward.name}`, search best return {best}, noise on "
             f"{'every decision' if args.noise_decisions < 0 else f'the first {args.noise_decisions} decisions'}, "
             f"{args.episodes} punches per sigma through PunchController in Godot ({godot_s:.0f} s, "
             f"{config['punches_per_s']} punches/s).", "",
             "| sigma | mean return | / search best | success (return > 0) | hit rate | impact spread (cm) | path spread (cm) |",
             "|---|---|---|---|---|---|---|"]
    for row in rows:
        ratio = f"{row['return_ratio']:.2f}" if row["return_ratio"] is not None else "-"
        lines.append(f"| {row['sigma']:.2f} | {row['mean_return']:.3f} | {ratio} | {100 * row['success_rate']:.1f}% | "
                     f"{100 * row['hit_rate']:.1f}% | {100 * row['impact_spread_m']:.1f} | {100 * row['path_spread_m']:.1f} |")
    lines += ["", *[f"![{p.stem}]({p.name})" for p in plots]]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out, rows


def replay_frames(frames_dir: Path, sigma_index: int, meta: dict[str, Any]) -> dict[str, np.ndarray]:
    """Godot's raw record of one sigma (with --keep-frames): features, observations, mean_actions, actions."""
    per_sigma = int(meta["episodes_per_sigma"])
    return {kind: np.array(recorded(frames_dir, meta, kind, sigma_index * per_sigma, per_sigma))
            for kind in KINDS if (frames_dir / f"{kind}.f32").exists()}
