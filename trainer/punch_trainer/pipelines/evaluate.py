"""`punch eval`: how well a policy punches wherever the target is, and under noise, on held-out placements.

The placements are drawn from the spec's reach volume with a seed that training never uses (`HELD_OUT_SEED`,
written into the report). Every punch runs in headless Godot through `PunchController` itself (as `punch
replay` does), in these conditions:

- noise on every decision, and on the first 4 decisions only, at each sigma (default 0, 0.1, 0.3, 0.5);
- sigma 0 with the bag already swinging (up to the volume's largest speed, random direction);
- sigma 0 starting from the end of an earlier punch.

Per condition: the success rate (a positive return and the right fist touched the bag) with its 95% interval
(`success_interval`: 64 placements tell a few points apart only roughly), the mean return as a
fraction of the trajectory search's best at that placement, and the spread of the impact points. With noise on
every decision, at each sigma: the naturalness figures (docs/naturalness.md), medians over the punches, beside
those of the four captured punches; and, where the capture is there, the paper's Fig. 4 (both fists and the
trunk against the capture) and a strip of stick figures, a captured punch above the policy's. The
per-placement search best comes from a short search at every held-out placement, warm-started from the
policy's own noise-free actions there (so it is at least the policy's own return, give or take the small
difference between the game and the training server). `--baseline` evaluates a second policy (today's
single-spot one, say) on the same placements for comparison.

    punch eval --policy runs/NAME/policy.onnx [--baseline OTHER.onnx] [--placements 64] [--sigmas 0,0.1,0.3,0.5]
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from punch_trainer.capture.bvh import DEFAULT_BVH
from punch_trainer.capture.punches import captured_punches
from punch_trainer.learn.reach import HELD_OUT_SEED, ReachVolume
from punch_trainer.learn.search import SearchArgs, placement_search
from punch_trainer.learn.volume import success, success_interval
from punch_trainer.options import bounds
from punch_trainer.pipelines.replay import ReplayArgs, ReplayError, analyse_sigma, run_godot_replay
from punch_trainer.policy_file import REACH_VOLUME, read_policy_metadata
from punch_trainer.report.naturalness import (
    NaturalnessSummary,
    capture_figures,
    naturalness_table,
    punches_naturalness,
    summarise,
)
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.placement import BagPlacement
from punch_trainer.sim.rewards import Reward, metadata_reward
from punch_trainer.sim.rollouts import RolloutPool

FIRST_DECISIONS = 4
"""the "first decisions only" noise condition (the paper's "Noise < 4")"""


@dataclass
class EvalArgs:
    policy: Path
    """the policy to evaluate (an exported .onnx)"""
    baseline: Path | None = None
    """a second policy evaluated on the same placements (e.g. a single-spot one)"""
    placements: int = 64
    """held-out placements drawn from the reach volume"""
    seed: int = HELD_OUT_SEED
    """seed of the placements (the default is one no training stage uses)"""
    sigmas: list[float] = field(default_factory=lambda: [0.0, 0.1, 0.3, 0.5])
    """noise sigmas (a,b,c or start:stop:step)"""
    noisy_episodes: int = 2
    """punches per placement at each sigma > 0 (sigma 0: one)"""
    search_iterations: int = field(default=20, metadata=bounds(0, 100_000))
    """iterations of the per-placement search (0: no search; fractions of the best are then left out)"""
    out: Path | None = None
    """output directory (default: next to the policy, eval_<time>)"""


def still_and_swinging_placements(reach: ReachVolume, count: int, seed: int) -> tuple[list[BagPlacement], list[BagPlacement]]:
    """`count` held-out placements at rest, and the same places with the bag swinging, from `seed`."""
    rng = np.random.default_rng(seed)
    still = reach.sample(rng, count)
    moving = reach.sample(rng, count, moving=1.0)
    moving = [dataclasses.replace(bag, distance_m=place.distance_m, height_m=place.height_m, side_m=place.side_m)
              for bag, place in zip(moving, still, strict=True)]
    return still, moving


def run_condition(policy: Path, bags: list[BagPlacement], sigmas: list[float], reward: Reward, *, episodes_per_bag: int = 1,
                  noise_decisions: int = -1, start: str = "guard", keep_actions: bool = False, keep_features: bool = False,
                  seed: int = 0) -> list[dict[str, Any]]:
    """Punches through PunchController in Godot at every placement of `bags` (`episodes_per_bag` each) for each
    sigma; per sigma: returns, success, the placement of every episode, the analysis of `punch replay` and every
    punch's naturalness figures (`keep_features`: also the features [episodes, frames, F] and their names)."""
    refuse_unreplayable(bags)
    physics_hz = float(read_policy_metadata(policy).physics_hz)
    with tempfile.TemporaryDirectory(prefix="punch_eval_") as directory:
        frames_dir = Path(directory)
        bags_file = frames_dir / "bags.json"
        bags_file.write_text(json.dumps([bag.to_wire() for bag in bags]))
        episodes = len(bags) * episodes_per_bag
        args = ReplayArgs(policy=policy, sigmas=sigmas, episodes=episodes, noise_decisions=noise_decisions, seed=seed,
                          bags=bags_file, start=start, characters=min(64, episodes))
        meta = run_godot_replay(args, frames_dir, progress=False)
        names = [str(n) for n in meta["feature_names"]]
        results = []
        for index, sigma in enumerate(sigmas):
            features = np.fromfile(frames_dir / f"features_{index}.f32", dtype="<f4").reshape(episodes, meta["frames"], len(names))
            analysis = analyse_sigma(features, names, reward)
            result = {"sigma": sigma, "returns": analysis["returns"], "success": success(analysis["returns"], features, names),
                      "placement": np.arange(episodes) % len(bags), "impact_spread_m": analysis["impact_spread_m"],
                      "naturalness": punches_naturalness(features, names, physics_hz), "physics_hz": physics_hz}
            if keep_features:
                result["features"], result["feature_names"] = features, names
            if keep_actions:
                actions = np.fromfile(frames_dir / f"actions_{index}.f32", dtype="<f4").reshape(episodes, meta["decisions"], -1)
                result["actions"] = actions
            results.append(result)
        return results


def refuse_unreplayable(bags: list[BagPlacement]) -> None:
    """ReplayError for a placement with more than tools/replay.gd plays (the bag's place and its swing): sized
    arms, a moving body, a gliding or riding bag would otherwise run silently as the scene's standing character."""
    for index, bag in enumerate(bags):
        replayed = BagPlacement(bag.distance_m, bag.height_m, bag.side_m, bag.velocity_side_mps, bag.velocity_forward_mps)
        if bag != replayed:
            extra = {name: value for name, value in bag.to_wire().items() if value != replayed.to_wire()[name]}
            raise ReplayError(f"placement {index} sets {extra}, which a replay does not play (it places and swings the "
                              "bag only): sized arms are `punch eval-sizes`'s, a moving body or target `punch eval-moving`'s")


def _condition_from_bytes(policy_bytes: bytes, **kwargs: Any) -> list[dict[str, Any]]:
    """`run_condition` on a Ray worker's node, which may not hold the policy file: its bytes travel instead."""
    with tempfile.TemporaryDirectory(prefix="punch_eval_policy_") as directory:
        policy = Path(directory) / "policy.onnx"
        policy.write_bytes(policy_bytes)
        return run_condition(policy, **kwargs)


def run_conditions(calls: list[dict[str, Any]], backend: Backend) -> list[list[dict[str, Any]]]:
    """`run_condition(**call)` for every call on `backend`: one after the other here, or side by side on a Ray
    cluster's workers (each its own Godot on some node; the results are the same either way)."""
    if backend.shares_files:
        return backend.map(run_condition, calls)
    policies = {call["policy"]: Path(call["policy"]).read_bytes() for call in calls}
    remote_calls = [{"policy_bytes": policies[call["policy"]], **{k: v for k, v in call.items() if k != "policy"}} for call in calls]
    return backend.map(_condition_from_bytes, remote_calls)


def search_bests(policy_actions: np.ndarray, bags: list[BagPlacement], reward: Reward, smoothing_window: int,
                 iterations: int, seed: int, backend: Backend) -> np.ndarray:
    """The best return a short trajectory search finds at each placement, warm-started from `policy_actions`
    [P, decisions, A] (the policy's own noise-free actions there)."""
    args = SearchArgs(reward=reward.name, frames=reward.frames, seed=seed, iterations=iterations, rollouts=16,
                      sigma_init=0.3, smoothing_window=smoothing_window, plateau_iterations=0)
    with RolloutPool(1, 64, backend=backend) as pool:
        results = placement_search(args, reward, pool, progress=False, placements=bags, init_mu=policy_actions, neighbours=0)
    return np.array([r.best_return for r in results])


def policy_reward(policy: Path) -> tuple[Reward, dict[str, str]]:
    """The reward a policy was trained for (from its metadata), and the metadata."""
    metadata = read_policy_metadata(policy).entries
    return metadata_reward(metadata, str(policy)), metadata


def evaluate_policy(policy: Path, args: EvalArgs, still: list[BagPlacement], moving: list[BagPlacement],
                    base: dict[str, Any], best: np.ndarray | None, backend: Backend) -> dict[str, Any]:
    """Every condition for one policy (`base`: its noise-free punches, already run): rows for the report."""
    reward, metadata = policy_reward(policy)
    noisy = [s for s in args.sigmas if s > 0]
    calls: list[tuple[str, dict[str, Any]]] = []
    if noisy:
        calls += [("every decision", {"bags": still, "sigmas": noisy, "episodes_per_bag": args.noisy_episodes}),
                  (f"first {FIRST_DECISIONS} decisions", {"bags": still, "sigmas": noisy, "episodes_per_bag": args.noisy_episodes,
                                                          "noise_decisions": FIRST_DECISIONS, "seed": 1})]
    calls += [("bag swinging", {"bags": moving, "sigmas": [0.0]}), ("after a punch", {"bags": still, "sigmas": [0.0], "start": "after_punch"})]
    results = run_conditions([{"policy": policy, "reward": reward, **call} for _, call in calls], backend)
    conditions = [("every decision", base)]
    for (name, _), per_sigma in zip(calls, results, strict=True):
        conditions += [(name, result) for result in per_sigma]
    rows = []
    for name, result in conditions:
        fraction = None
        if best is not None:
            scored = best[result["placement"]] > 0  # a placement where nothing scores has no fraction
            fraction = float(np.mean(result["returns"][scored] / best[result["placement"]][scored])) if scored.any() else None
        rows.append({"condition": name, "sigma": result["sigma"], "episodes": len(result["returns"]),
                     "success_rate": float(result["success"].mean()),
                     "success_interval": success_interval(int(result["success"].sum()), len(result["success"])),
                     "return_fraction_of_search_best": fraction,
                     "impact_spread_m": result["impact_spread_m"]})
    naturalness = [{"sigma": result["sigma"], **summarise(result["naturalness"]).to_json()}
                   for name, result in conditions if name == "every decision"]
    return {"policy": str(policy), "reward": reward.name, "reach": metadata[REACH_VOLUME], "rows": rows,
            "success_at_sigma0": base["success"].tolist(), "naturalness": naturalness,
            "naturalness_at_sigma0": [punch.to_json() for punch in base["naturalness"]]}


def plot_naturalness(out: Path, base: dict[str, Any], placements: list[BagPlacement], suffix: str = "") -> list[Path]:
    """Fig. 4 of a policy's noise-free punches (`base`, with features) against the capture, and the stick-figure
    strip of its punch at the placement nearest the middle of `placements`."""
    from punch_trainer.report.naturalness_plots import plot_capture_comparison, plot_stick_strip

    capture = captured_punches(DEFAULT_BVH)
    points = np.array([[p.distance_m, p.height_m, p.side_m] for p in placements])
    spread = np.where(points.std(axis=0) > 0, points.std(axis=0), 1.0)
    middle = int(np.argmin(np.linalg.norm((points - points.mean(axis=0)) / spread, axis=1)))
    features, names, hz = base["features"], base["feature_names"], base["physics_hz"]
    return [plot_capture_comparison(out, features, names, hz, capture, file_name=f"naturalness_fig4{suffix}.png"),
            plot_stick_strip(out, features[middle], names, hz, capture[0], file_name=f"naturalness_strip{suffix}.png")]


def run_eval(args: EvalArgs, progress: bool = True, *, backend: Backend = LOCAL) -> tuple[Path, dict[str, Any]]:
    """The whole `punch eval` command, every punch and search on `backend`: writes eval.json and report.md."""
    started = time.perf_counter()
    with RolloutPool(1, 1, backend=backend) as pool:
        reach = ReachVolume.from_json(pool.info.reach_volume)
    still, moving = still_and_swinging_placements(reach, args.placements, args.seed)
    out = Path(args.out or Path(args.policy).parent / f"eval_{int(time.time())}")
    out.mkdir(parents=True, exist_ok=True)
    policies = [Path(args.policy)] + ([Path(args.baseline)] if args.baseline else [])
    reward, metadata = policy_reward(policies[0])
    if any(policy_reward(p)[0].name != reward.name for p in policies):
        raise ReplayError("--baseline must be trained for the same reward as --policy")
    if progress:
        print(f"punching at {len(still)} held-out placements, sigma 0 ...", flush=True)
    bases = [runs[0] for runs in run_conditions([{"policy": policy, "bags": still, "sigmas": [0.0], "reward": reward, "keep_actions": True,
                                                   "keep_features": True} for policy in policies], backend)]
    best = None
    if args.search_iterations > 0:
        if progress:
            print("searching the best punch at every placement ...", flush=True)
        best = search_bests(bases[0]["actions"], still, reward, read_policy_metadata(policies[0]).smoothing_window,
                            args.search_iterations, args.seed, backend)
        best = np.max([best, *[base["returns"] for base in bases]], axis=0)  # a policy may beat the short search
    evaluations = []
    for policy, base in zip(policies, bases, strict=True):
        if progress:
            print(f"evaluating {policy} ...", flush=True)
        evaluations.append(evaluate_policy(policy, args, still, moving, base, best, backend))
    capture = capture_figures()
    report = {"seed": args.seed, "placements": [bag.to_wire() for bag in still], "moving_placements": [bag.to_wire() for bag in moving], "reach": json.loads(reach.to_json()),
              "search_best": best.tolist() if best is not None else None, "evaluations": evaluations,
              "captured_naturalness": [punch.to_json() for punch in capture] if capture else None,
              "wall_s": round(time.perf_counter() - started, 1)}
    (out / "eval.json").write_text(json.dumps(report, indent=2) + "\n")

    from punch_trainer.report.plots import plot_eval

    plots = plot_eval(out, report["placements"], evaluations)
    naturalness_plots = {index: plot_naturalness(out, base, still, "" if index == 0 else "_baseline") for index, base in enumerate(bases)}
    lines = [f"# punch eval: {args.policy}", "",
             f"{len(still)} held-out placements drawn from the reach volume with seed {args.seed} (a seed no training "
             f"stage uses); {args.noisy_episodes} punches per placement at each sigma > 0; every punch through "
             f"PunchController in headless Godot ({report['wall_s']:.0f} s in all). Success: a positive return and the "
             "right fist touched the bag; its interval: Wilson's 95% score interval, where the rate at other placements "
             "could lie. Return: the mean of return / the best return known at that placement (a "
             f"{args.search_iterations}-iteration search warm-started from the first policy's punch, or a policy's own "
             "noise-free punch if better); placements where nothing scores are left out.", ""]
    for index, evaluation in enumerate(evaluations):
        lines += [f"## {evaluation['policy']} (reward `{evaluation['reward']}`)", "",
                  "| noise on | sigma | punches | success | its 95% interval | return / best known | impact spread (cm) |",
                  "|---|---|---|---|---|---|---|"]
        for row in evaluation["rows"]:
            fraction = f"{row['return_fraction_of_search_best']:.2f}" if row["return_fraction_of_search_best"] is not None else "-"
            low, high = row["success_interval"]
            lines.append(f"| {row['condition']} | {row['sigma']:.2f} | {row['episodes']} | {100 * row['success_rate']:.1f}% | "
                         f"{100 * low:.1f}-{100 * high:.1f}% | {fraction} | {100 * row['impact_spread_m']:.1f} |")
        lines += ["", "Naturalness (docs/naturalness.md): medians over the punches, noise on every decision; the captured "
                  "punches' range from movement onset to full reach.", ""]
        lines += naturalness_table([(f"sigma {row['sigma']:g}", NaturalnessSummary.from_json(row)) for row in evaluation["naturalness"]], capture)
        lines += ["", *[f"![{p.stem}]({p.name})" for p in naturalness_plots[index]], ""]
    lines += [f"![{p.stem}]({p.name})" for p in plots]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out, report
