"""Replay experiment (the paper's Fig. 10-11): how a trained policy's punches vary with the runtime noise sigma.

The punches run in headless Godot through `PunchController` itself (godot_project/tools/replay.gd), the same
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
import os
import selectors
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.errors import GodotRunError, PunchError
from punch_trainer.learn.reach import ReachVolume
from punch_trainer.options import SIGMA
from punch_trainer.policy_file import PolicyMetadata, read_entries, read_policy_metadata
from punch_trainer.sim.conditions import EpisodeConditions
from punch_trainer.sim.godot import FATAL_LOG_PATTERNS, GODOT_PROJECT, start_godot, stop_godot, tail
from punch_trainer.sim.rewards import Reward, first_right_contact, metadata_reward, score

KINDS = ("features", "observations", "mean_actions", "actions")
# Paths drawn per sigma in the Fig. 11 plot.
PLOTTED_PATHS = 40


class ReplayError(PunchError):
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
    bags: Path | None = None
    """a JSON list of bag placements, episode e at entry e modulo its length (default: --bag or the spec's)"""
    start: str = "guard"
    """'guard', or 'after_punch': every recorded punch starts where an earlier one ended"""
    timeout_s: float = 3600.0
    """how long Godot may take for the whole replay"""


def parse_sigmas(text: str) -> list[float]:
    """`0.1:0.9:0.1` (start:stop:step, inclusive) or `0,0.3,0.5`; at most SIGMA.max_items of them (their bounds
    are checked with every option's, punch_trainer/options.py)."""
    try:
        if ":" in text:
            start, stop, step = (float(v) for v in text.split(":"))
            if not all(map(math.isfinite, (start, stop, step))) or step <= 0:
                raise ValueError("start, stop and step must be finite, and step > 0")
            count = math.floor((stop - start) / step + 0.5) + 1
            if not 1 <= count <= (SIGMA.max_items or 0):
                raise ValueError(f"that is {max(count, 0)} sigmas; at least 1 and at most {SIGMA.max_items}")
            return [round(start + i * step, 6) for i in range(count)]
        return [float(v) for v in text.split(",")]
    except ValueError as error:
        raise ReplayError(f"bad --sigmas '{text}' (use start:stop:step or a,b,c): {error}") from None


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


def policy_placements(policy: Path, count: int, seed: int) -> list[EpisodeConditions]:
    """`count` held-out placements at rest from the policy's reach volume (its metadata's), drawn by `ReachVolume.sample`
    as `punch eval` draws its held-out ones, from `seed`."""
    reach = ReachVolume.from_json(read_policy_metadata(policy).reach_volume)
    return reach.sample(np.random.default_rng(seed), count)


def run_godot_replay(args: ReplayArgs, frames_dir: Path, progress: bool = True, idle_frames: int = 0) -> dict[str, Any]:
    """Runs tools/replay.gd; returns its meta.json. Raises ReplayError when Godot fails. `idle_frames`: frames
    each batch stands idle after its punches (for `punch bench inference`)."""
    command = [
        "--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", "res://tools/replay.gd", "--",
        f"--policy={Path(args.policy).resolve()}", f"--sigmas={','.join(map(str, args.sigmas))}",
        f"--episodes={args.episodes}", f"--out={frames_dir.resolve()}", f"--noise-decisions={args.noise_decisions}",
        f"--characters={args.characters}", f"--characters-per-world={args.characters_per_world}", f"--seed={args.seed}",
        f"--start={args.start}", f"--idle-frames={idle_frames}",
        *([f"--bags={Path(args.bags).resolve()}"] if args.bags else []),
    ]
    log: list[str] = []
    total_punches = len(args.sigmas) * args.episodes
    deadline = time.monotonic() + args.timeout_s
    process = start_godot(command)
    assert process.stdout is not None
    # The deadline is kept by the clock, not by Godot's output: a Godot that hangs silently is stopped too.
    selector = selectors.DefaultSelector()
    selector.register(process.stdout, selectors.EVENT_READ)
    with tqdm(total=total_punches, desc="replay (Godot)", unit="punch", disable=not progress) as bar:
        try:
            while True:
                left_s = deadline - time.monotonic()
                if left_s <= 0 or not selector.select(timeout=left_s):
                    raise ReplayError(f"the replay did not finish within {args.timeout_s:.0f} s (Godot was stopped):\n"
                                      f"{tail(''.join(log))}")
                line = process.stdout.readline()
                if not line:
                    break
                log.append(line)
                if line.startswith("REPLAY_PROGRESS "):
                    bar.update(int(line.split()[1]) - bar.n)
            process.wait(timeout=60)
        finally:
            selector.close()
            stop_godot(process)
    text = "".join(log)
    fatal = [line for line in log if any(p in line for p in FATAL_LOG_PATTERNS) or line.startswith("error: replay")]
    if process.returncode != 0 or fatal or "REPLAY_DONE" not in text:
        raise GodotRunError(f"the Godot replay failed (exit code {process.returncode}):\n{tail(text)}", text)
    meta: dict[str, Any] = json.loads((frames_dir / "meta.json").read_text())
    return meta


def analyse_sigma(features: np.ndarray, names: list[str], reward: Reward, chunk: int = 2000) -> dict[str, Any]:
    """Returns, success and spreads of one sigma's punches, features [episodes, frames, F] (may be a memmap)."""
    col = names.index
    returns = np.concatenate([score(reward, np.asarray(features[i:i + chunk], dtype=np.float64), names)
                              for i in range(0, len(features), chunk)])
    fist = np.asarray(features[:, :, col("fist_r_pos_x"):col("fist_r_pos_z") + 1], dtype=np.float64)
    hit, first = first_right_contact(features, names)
    impacts = fist[np.flatnonzero(hit), first[hit]]
    return {
        "returns": returns,
        "fist_paths": fist,
        "impacts": impacts,
        "hit_rate": float(hit.mean()),
        # Mean over frames of the distance of each path from the mean path: how far punches wander apart.
        "path_spread_m": float(np.linalg.norm(fist - fist.mean(axis=0), axis=-1).mean()),
        "impact_spread_m": float(np.linalg.norm(impacts - impacts.mean(axis=0), axis=-1).mean()) if len(impacts) > 1 else 0.0,
    }


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
        features = np.memmap(frames_dir / f"features_{index}.f32", dtype="<f4", mode="r").reshape(args.episodes, meta["frames"], len(names))
        analysis = analyse_sigma(features, names, reward)
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
        for index in range(len(args.sigmas)):
            for kind in KINDS:
                (frames_dir / f"{kind}_{index}.f32").unlink(missing_ok=True)

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
    shapes = {"features": (meta["frames"], len(meta["feature_names"])), "observations": (meta["decisions"], -1),
              "mean_actions": (meta["decisions"], -1), "actions": (meta["decisions"], -1)}
    return {kind: np.fromfile(frames_dir / f"{kind}_{sigma_index}.f32", dtype="<f4").reshape(meta["episodes"], *shapes[kind])
            for kind in KINDS if os.path.exists(frames_dir / f"{kind}_{sigma_index}.f32")}
