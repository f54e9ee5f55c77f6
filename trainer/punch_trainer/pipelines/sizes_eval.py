"""`punch eval-sizes`: how often a policy's punches hit when its character's arms are sized to other bodies, as
`PunchSkeletonModifier` (`size_to_rig`) sizes them to a game's rig (README, "Your own character").

Every punch runs in headless Godot through `PunchController` (godot_project/tools/sized_hits.gd): each character's
arms are sized with `PunchCharacter.size_arms` before it punches, its upper arm and forearm (elbow to fist centre)
both times the scale, its shoulders as they are. The placements are the held-out sampler's (`ReachVolume.sample`,
as `punch eval` draws them) from the policy's reach volume, unchanged by the scale: the issue asks for hits
anywhere in the reach volume for arms 0.75 to 1.25 times the simulated body's, and no eval counts a target
beyond what an arm can reach apart. A hit: the controller's `hit` signal on the target during the punch.

    punch eval-sizes --policy P.onnx [--scales 0.75,0.85,1.0,1.15,1.25]
        [--proportions 0.7x0.85,0.85x0.7,1.3x1.1,1.1x1.3] [--sigmas 0,0.3] [--placements 32] [--seed 4242] [--out DIR]
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.learn.volume import success_interval
from punch_trainer.options import bounds, check_options
from punch_trainer.pipelines.replay import ReplayError, policy_placements
from punch_trainer.sim.godot import run_godot_tool
from punch_trainer.sim.placement import (
    ARM_SCALE_RANGE,
    SCENE_ARM_LENGTHS_M,
    SEGMENT_SCALE_RANGE,
    BagPlacement,
    arm_scale,
)

SIZES_SEED = 4242
"""the placements' and noise's default seed (training seeds are small integers: 0 and the next two)"""


class SizesEvalError(ReplayError):
    """`punch eval-sizes` could not run: an arm scale `size_arms` refuses, a bad policy file, or Godot failed."""


def check_scales(scales: list[float]) -> list[float]:
    """The scales as given; SizesEvalError names a scale outside the range `size_arms` accepts, and the range."""
    low, high = ARM_SCALE_RANGE
    refused = [scale for scale in scales if not low <= scale <= high]
    if refused:
        raise SizesEvalError(f"arm scale {', '.join(f'{scale:g}' for scale in refused)} is outside the range "
                             f"PunchCharacter.size_arms accepts: {low:g} to {high:g} times the character scene's arm "
                             f"(shoulder to fist centre {sum(SCENE_ARM_LENGTHS_M[:2]):.3f} m)")
    return scales


def parse_proportions(text: str) -> list[tuple[float, float]]:
    """`0.7x0.85,1.3x1.1`: upper arm and forearm scales of rigs with other proportions than the scene's (their
    ranges are checked by `check_proportions`); a bare `0.8` is both lengths times 0.8."""
    try:
        sizes = [item.split("x") for item in text.split(",") if item.strip()]
        if any(len(size) not in (1, 2) for size in sizes):
            raise ValueError("one or two scales per size")
        return [(float(size[0]), float(size[-1])) for size in sizes]
    except ValueError as error:
        raise SizesEvalError(f"bad --proportions '{text}' (use UPPERxFOREARM,...: 0.7x0.85,1.3x1.1): {error}") from None


def check_proportions(proportions: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The proportions as given; SizesEvalError names one whose segment or arm `size_arms` would refuse."""
    for upper, forearm in proportions:
        arm = arm_scale(upper, forearm)
        segments_ok = all(SEGMENT_SCALE_RANGE[0] <= v <= SEGMENT_SCALE_RANGE[1] for v in (upper, forearm))
        if not (segments_ok and ARM_SCALE_RANGE[0] <= arm <= ARM_SCALE_RANGE[1]):
            raise SizesEvalError(f"proportions {upper:g}x{forearm:g} are outside what PunchCharacter.size_arms "
                                 f"accepts: each length {SEGMENT_SCALE_RANGE[0]:g} to {SEGMENT_SCALE_RANGE[1]:g} times "
                                 f"the scene's, the arm {ARM_SCALE_RANGE[0]:g} to {ARM_SCALE_RANGE[1]:g} times "
                                 f"(these make it {arm:.3f})")
    return proportions


def size_label(upper: float, forearm: float) -> str:
    """`0.75` for both lengths times 0.75, `0.7x0.85` for other proportions."""
    return f"{upper:g}" if upper == forearm else f"{upper:g}x{forearm:g}"


def parse_scales(text: str) -> list[float]:
    """`0.75,1,1.25`: arm scales (their range is checked with the other options, by `check_scales`)."""
    try:
        return [float(value) for value in text.split(",")]
    except ValueError as error:
        raise SizesEvalError(f"bad --scales '{text}' (use a,b,c): {error}") from None


@dataclass
class SizesEvalArgs:
    policy: Path
    """the policy to measure (an exported .onnx)"""
    scales: list[float] = field(default_factory=lambda: [0.75, 0.85, 1.0, 1.15, 1.25],
                                metadata=bounds(*ARM_SCALE_RANGE, max_items=20))
    """arm scales (a,b,c): upper arm and forearm both times the scale, the shoulders as they are; PunchCharacter.size_arms
    accepts arms 0.75 to 1.25 times the character scene's"""
    proportions: list[tuple[float, float]] = field(
        default_factory=lambda: [(0.7, 0.85), (0.85, 0.7), (1.3, 1.1), (1.1, 1.3)],
        metadata=bounds(*SEGMENT_SCALE_RANGE, max_items=20))
    """rigs with other proportions than the scene's (UPPERxFOREARM,...: upper arm and forearm scales, as training
    draws them), measured after the scales"""
    sigmas: list[float] = field(default_factory=lambda: [0.0, 0.3])
    """runtime noise sigmas, on every decision (a,b,c or start:stop:step)"""
    placements: int = 32
    """held-out placements drawn from the policy's reach volume (one punch per placement, scale and sigma)"""
    seed: int = SIZES_SEED
    """seed of the placements and of the runtime noise"""
    out: Path | None = None
    """output directory (default: next to the policy, eval_sizes_<time>)"""
    timeout_s: float = 3600.0
    """how long Godot may take for the punches"""


def run_sized_hits(policy: Path, bags: list[BagPlacement], sizes: list[tuple[float, float]], sigmas: list[float], seed: int,
                   timeout_s: float, on_progress: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Runs tools/sized_hits.gd; returns its output: `arm_scale_range` (Godot's) and `rows`, one per punch:
    [size index, sigma index, placement index, hits on the target, out-of-reach signals, how the punch ended,
    upper arm, forearm, shoulder width (m, as `arm_lengths()` reports them sized)]. `sizes`: (upper arm scale,
    forearm scale) each. A size Godot's `size_arms` refuses ends in GodotRunError with its message."""
    with tempfile.TemporaryDirectory(prefix="punch_sizes_") as directory:
        folder = Path(directory)
        (folder / "bags.json").write_text(json.dumps([bag.to_wire() for bag in bags]))
        out = folder / "hits.json"
        run_godot_tool("sized_hits", {"policy": Path(policy).resolve(), "bags": folder / "bags.json", "out": out,
                                      "scales": ",".join(f"{u}x{f}" for u, f in sizes), "sigmas": ",".join(map(str, sigmas)),
                                      "seed": seed},
                       what="the sized punches", timeout_s=timeout_s, on_progress=on_progress, timeout_error=SizesEvalError)
        result: dict[str, Any] = json.loads(out.read_text())
        return result


def tally(rows: list[list[Any]], sizes: list[tuple[float, float]], sigmas: list[float]) -> list[dict[str, Any]]:
    """Per size: the arm lengths Godot reported (median over its characters, m) and, at each sigma, hits and
    punches."""
    result = []
    for size_index, (upper, forearm) in enumerate(sizes):
        mine = [row for row in rows if row[0] == size_index]
        lengths = np.median(np.array([row[6:9] for row in mine], dtype=float), axis=0) if mine else np.zeros(3)
        per_sigma = []
        for sigma_index, sigma in enumerate(sigmas):
            punches = [row for row in mine if row[1] == sigma_index]
            per_sigma.append({"sigma": sigma, "hits": sum(1 for row in punches if row[3] > 0), "punches": len(punches),
                              "out_of_reach": sum(1 for row in punches if row[4] > 0),
                              "missed_placements": sorted(int(row[2]) for row in punches if row[3] == 0)})
        result.append({"scale": size_label(upper, forearm), "upper_arm_scale": upper, "forearm_scale": forearm,
                       "upper_arm_m": round(float(lengths[0]), 4), "forearm_m": round(float(lengths[1]), 4),
                       "shoulder_width_m": round(float(lengths[2]), 4), "per_sigma": per_sigma})
    return result


def hits_cell(hits: int, punches: int) -> str:
    """hits/punches (%; its 95% interval)."""
    low, high = success_interval(hits, punches)
    return f"{hits}/{punches} ({100 * hits / max(punches, 1):.0f}%; {100 * low:.0f}-{100 * high:.0f}%)"


def markdown_table(report: dict[str, Any]) -> list[str]:
    """Rows: arm scales (UPPERxFOREARM for other proportions), with the arm lengths Godot reported; columns: sigma,
    each hits/punches (%; its 95% interval, `success_interval`)."""
    sigmas = report["sigmas"]
    header = ["arm scale", "upper arm (m)", "forearm (m)", "shoulders (m)"] + [f"σ {sigma:g}" for sigma in sigmas]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for size in report["sizes"]:
        cells = [hits_cell(s["hits"], s["punches"]) + (f", {s['out_of_reach']} out of reach" if s["out_of_reach"] else "")
                 for s in size["per_sigma"]]
        lines.append(f"| {size['scale']} | {size['upper_arm_m']:.3f} | {size['forearm_m']:.3f} | "
                     f"{size['shoulder_width_m']:.3f} | " + " | ".join(cells) + " |")
    return lines


def run_sizes_eval(args: SizesEvalArgs, progress: bool = True) -> tuple[Path, dict[str, Any]]:
    """The whole `punch eval-sizes` command: writes sizes.json and report.md in the output directory."""
    started = time.perf_counter()
    check_scales(args.scales)
    check_proportions(args.proportions)
    check_options(args)
    sizes = [(scale, scale) for scale in args.scales] + list(args.proportions)
    bags = policy_placements(Path(args.policy), args.placements, args.seed)
    out = Path(args.out or Path(args.policy).parent / f"eval_sizes_{int(time.time())}")
    out.mkdir(parents=True, exist_ok=True)
    total = len(bags) * len(sizes) * len(args.sigmas)
    with tqdm(total=total, desc="sized punches (Godot)", unit="punch", disable=not progress) as bar:
        def advance(done: int) -> None:
            bar.update(done - bar.n)

        result = run_sized_hits(Path(args.policy), bags, sizes, args.sigmas, args.seed, args.timeout_s, advance)
    report = {"policy": str(args.policy), "seed": args.seed, "scales": args.scales,
              "proportions": [size_label(*p) for p in args.proportions], "sigmas": args.sigmas,
              "arm_scale_range": result["arm_scale_range"], "scene_arm_lengths_m": list(SCENE_ARM_LENGTHS_M),
              "placements": [bag.to_wire() for bag in bags], "sizes": tally(result["rows"], sizes, args.sigmas),
              "wall_s": round(time.perf_counter() - started, 1)}
    (out / "sizes.json").write_text(json.dumps(report, indent=2) + "\n")
    lines = [f"# punch eval-sizes: {args.policy}", "",
             f"{len(bags)} held-out placements (seed {args.seed}) in the policy's reach volume, one punch per "
             f"placement, arm scale and sigma (noise on every decision), through PunchController in headless Godot "
             f"({report['wall_s']:.0f} s in all). Each character's upper arm and forearm are both times the scale "
             "(`PunchCharacter.size_arms`), or by the two scales of UPPERxFOREARM, the shoulders as they are; the lengths are those `arm_lengths()` "
             "reports. A hit: the controller's `hit` signal on the target during the punch; after each rate, its 95% interval "
             "(Wilson's), where the rate at other placements could lie.", "",
             *markdown_table(report)]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out, report
