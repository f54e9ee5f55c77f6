"""`punch eval-moving`: how often a policy's punches hit while its character walks, turns and steps in, and
while its target moves, moved as a game moves them (issue 31; docs/moving.md).

Every punch runs in headless Godot through `PunchController` (godot_project/tools/moving_hits.gd): the
character and its controller are children of a holder Node3D that a `_physics_process` moves every physics
frame from the frame the punch starts until it finishes, as a game moves its CharacterBody3D. Two kinds of case
(`MOVING_CASES`): the target rides along (the sandbag is a child of the same holder and stays where it was
relative to the character), or the character stands and the target's hook moves. The placements are the held-out
sampler's (`ReachVolume.sample`, as `punch eval` draws them) with a seed of their own (`MOVING_HELD_OUT_SEED`),
so neither training nor `punch eval` uses them. A hit: the controller's `hit` signal on the target during the punch.

    punch eval-moving --policy P.onnx [--baseline OTHER.onnx] [--placements 32] [--sigmas 0,0.3] [--arms 0.85x0.7]
        [--out DIR]
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from tqdm import tqdm

from punch_trainer.learn.reach import HELD_OUT_SEED
from punch_trainer.options import bounds
from punch_trainer.pipelines.replay import ReplayError, policy_placements
from punch_trainer.pipelines.sizes_eval import size_label
from punch_trainer.sim.godot import run_godot_tool
from punch_trainer.sim.placement import SEGMENT_SCALE_RANGE, BagPlacement

MOVING_HELD_OUT_SEED = HELD_OUT_SEED - 31
"""the placements' seed: neither a training seed nor `punch eval`'s (31: the issue)"""


@dataclass(frozen=True)
class MotionCase:
    """One way of moving, from the punch's first frame to its last (moving_hits.gd applies it). Vectors are in
    the moving node's own frame at the start: [left, up, forward] (m/s)."""

    name: str
    target: Literal["ride", "moving"]
    """"ride": the character's holder moves, its sandbag riding along; "moving": the character stands and the
    target's hook moves"""
    velocity_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turn_dps: float = 0.0
    """about the vertical through the character's root, positive to the left"""
    lunge_m: float = 0.0
    """forward, over `lunge_s`, minimum-jerk (starts and stops smoothly)"""
    lunge_s: float = 0.25
    bob_m: float = 0.0
    """vertical amplitude of a sine at `bob_hz`"""
    bob_hz: float = 2.0
    trained_on: bool = True
    """false: an off-grid case (a speed or direction not in the issue's list of training motions)"""


def _walk(name: str, left: float, forward: float, **kwargs: Any) -> MotionCase:
    return MotionCase(name, "ride", (left, 0.0, forward), **kwargs)


def _target(name: str, speed: float, toward: str, *, trained_on: bool = True) -> MotionCase:
    """The target moving at `speed` (m/s): "toward" the character, "away", to the character's "left" or
    "right", or "diagonal" (away and to the left at 45°)."""
    left, forward = {"toward": (0.0, -1.0), "away": (0.0, 1.0), "left": (1.0, 0.0), "right": (-1.0, 0.0),
                     "diagonal": (0.5**0.5, 0.5**0.5)}[toward]
    return MotionCase(name, "moving", (speed * left, 0.0, speed * forward), trained_on=trained_on)


MOVING_CASES: tuple[MotionCase, ...] = (
    _walk("standing", 0.0, 0.0),
    _walk("forward 0.7 m/s", 0.0, 0.7),
    _walk("forward 1.4 m/s", 0.0, 1.4),
    _walk("backward 0.7 m/s", 0.0, -0.7),
    _walk("right 0.7 m/s", -0.7, 0.0),
    _walk("right 1.4 m/s", -1.4, 0.0),
    _walk("left 0.7 m/s", 0.7, 0.0),
    _walk("left 1.4 m/s", 1.4, 0.0),
    _walk("turning left 90°/s", 0.0, 0.0, turn_dps=90.0),
    _walk("turning right 90°/s", 0.0, 0.0, turn_dps=-90.0),
    _walk("turning left 120°/s", 0.0, 0.0, turn_dps=120.0),
    _walk("turning right 120°/s", 0.0, 0.0, turn_dps=-120.0),
    _walk("step-in lunge 0.3 m in 0.25 s", 0.0, 0.0, lunge_m=0.3, lunge_s=0.25),
    _walk("forward 1.0 m/s, bob ±3 cm at 2 Hz", 0.0, 1.0, bob_m=0.03, bob_hz=2.0),
    _walk("off-grid: diagonal forward-right 1.0 m/s", -(0.5**0.5), 0.5**0.5, trained_on=False),
    _walk("off-grid: arc, 0.5 m/s turning right 60°/s", 0.0, 0.5, turn_dps=-60.0, trained_on=False),
    _walk("off-grid: backward-left 1.1 m/s", 0.55, -0.95, trained_on=False),
    _walk("off-grid: circling, left 1.0 m/s turning right 80°/s", 1.0, 0.0, turn_dps=-80.0, trained_on=False),
    _walk("beyond training: forward 2.0 m/s", 0.0, 2.0, trained_on=False),
    _walk("beyond training: turning left 180°/s", 0.0, 0.0, turn_dps=180.0, trained_on=False),
    _target("target toward 1.0 m/s", 1.0, "toward"),
    _target("target away 1.0 m/s", 1.0, "away"),
    _target("target to the left 1.0 m/s", 1.0, "left"),
    _target("target to the right 1.0 m/s", 1.0, "right"),
    _target("target toward 0.5 m/s", 0.5, "toward"),
    _target("target away 0.5 m/s", 0.5, "away"),
    _target("target to the left 0.5 m/s", 0.5, "left"),
    _target("target to the right 0.5 m/s", 0.5, "right"),
    _target("off-grid: target away-left 0.8 m/s", 0.8, "diagonal", trained_on=False),
)


class MovingEvalError(ReplayError):
    """`punch eval-moving` could not run: bad arguments, a bad policy file, or Godot failed."""


@dataclass
class MovingEvalArgs:
    policy: Path
    """the policy to measure (an exported .onnx)"""
    baseline: Path | None = None
    """a second policy measured on the same placements and cases, side by side"""
    placements: int = 32
    """held-out placements drawn from the policy's reach volume (one punch per placement, case and sigma)"""
    seed: int = MOVING_HELD_OUT_SEED
    """seed of the placements and of the runtime noise (the default is one neither training nor punch eval uses)"""
    sigmas: list[float] = field(default_factory=lambda: [0.0, 0.3])
    """runtime noise sigmas, on every decision (a,b,c or start:stop:step)"""
    cases: list[str] | None = None
    """motion cases to run, by name (default: all; docs/moving.md lists them)"""
    out: Path | None = None
    """output directory (default: next to the policy, eval_moving_<time>)"""
    lead_s: float = 0.5
    """how long a moving character has been moving when it punches, s (its bag riding along at its velocity;
    a lunge starts with the punch); 0: it starts moving with the punch, from standing"""
    arms: list[tuple[float, float]] = field(default_factory=lambda: [(1.0, 1.0)],
                                            metadata=bounds(*SEGMENT_SCALE_RANGE, max_items=1))
    """the characters' arms (S, or UPPERxFOREARM): sized through PunchCharacter.size_arms as `punch eval-sizes`
    sizes them (the upper arm and forearm times these, the shoulders as they are); 1: the scene's own"""
    timeout_s: float = 3600.0
    """how long Godot may take for one policy's punches"""


def select_cases(names: list[str] | None) -> list[MotionCase]:
    """The cases named (all when None), in MOVING_CASES's order; MovingEvalError names an unknown one."""
    if names is None:
        return list(MOVING_CASES)
    known = {case.name: case for case in MOVING_CASES}
    unknown = [name for name in names if name not in known]
    if unknown:
        raise MovingEvalError(f"unknown motion case(s) {', '.join(map(repr, unknown))}; the cases are: "
                              f"{', '.join(known)}")
    return [case for case in MOVING_CASES if case.name in names]


def run_moving_hits(policy: Path, bags: list[BagPlacement], cases: list[MotionCase], sigmas: list[float], seed: int,
                    timeout_s: float, on_progress: Callable[[int], None] | None = None,
                    lead_s: float = 0.0, arms: tuple[float, float] = (1.0, 1.0)) -> list[list[Any]]:
    """Runs tools/moving_hits.gd for one policy, its characters' arms sized by `arms` (upper arm, forearm scales);
    its rows: [sigma index, case index, placement index, hits on the target, out-of-reach signals, how the punch
    ended, metres the moved node went, metres outside the reach volume the target was at the start]."""
    with tempfile.TemporaryDirectory(prefix="punch_moving_") as directory:
        folder = Path(directory)
        (folder / "bags.json").write_text(json.dumps([bag.to_wire() for bag in bags]))
        (folder / "cases.json").write_text(json.dumps([asdict(case) for case in cases]))
        out = folder / "hits.json"
        run_godot_tool("moving_hits", {"policy": Path(policy).resolve(), "bags": folder / "bags.json",
                                       "cases": folder / "cases.json", "out": out, "sigmas": ",".join(map(str, sigmas)),
                                       "seed": seed, "lead-s": lead_s, "arms": f"{arms[0]},{arms[1]}"},
                       what="the moving punches", timeout_s=timeout_s, on_progress=on_progress, timeout_error=MovingEvalError)
        rows: list[list[Any]] = json.loads(out.read_text())["rows"]
        return rows


def tally(rows: list[list[Any]], cases: list[MotionCase], sigmas: list[float]) -> list[dict[str, Any]]:
    """Per case: hits and punches at each sigma, and how far the moved node went (median, m)."""
    result = []
    for case_index, case in enumerate(cases):
        per_sigma = []
        for sigma_index, sigma in enumerate(sigmas):
            mine = [row for row in rows if row[0] == sigma_index and row[1] == case_index]
            in_reach = [row for row in mine if row[4] == 0]
            per_sigma.append({"sigma": sigma, "hits": sum(1 for row in mine if row[3] > 0), "punches": len(mine),
                              "out_of_reach": len(mine) - len(in_reach),
                              "in_reach_hits": sum(1 for row in in_reach if row[3] > 0),
                              "out_of_reach_m": sorted(float(row[7]) for row in mine if row[4] > 0),
                              "hit_placements": sorted(int(row[2]) for row in mine if row[3] > 0)})
        moved = [float(row[6]) for row in rows if row[1] == case_index]
        result.append({"case": case.name, "target": case.target, "trained_on": case.trained_on,
                       "moved_m": float(np.median(moved)) if moved else 0.0, "per_sigma": per_sigma})
    return result


def markdown_table(report: dict[str, Any]) -> list[str]:
    """Rows: cases; columns: policy x sigma, each hits/punches, and, where some punches started with the target
    outside the policy's reach volume (a bag swung out on its hook), the hits of those that started in reach."""
    evaluations = report["evaluations"]
    header = ["case"] + [f"{Path(e['policy']).stem} σ {s['sigma']:g}" for e in evaluations for s in e["cases"][0]["per_sigma"]]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for index, case in enumerate(evaluations[0]["cases"]):
        cells = [f"{s['hits']}/{s['punches']}" + (f" ({s['in_reach_hits']}/{s['punches'] - s['out_of_reach']} in reach)"
                                                 if s["out_of_reach"] else "")
                 for e in evaluations for s in e["cases"][index]["per_sigma"]]
        lines.append(f"| {case['case']} | " + " | ".join(cells) + " |")
    return lines


def run_moving_eval(args: MovingEvalArgs, progress: bool = True) -> tuple[Path, dict[str, Any]]:
    """The whole `punch eval-moving` command: writes moving.json and report.md in the output directory."""
    started = time.perf_counter()
    cases = select_cases(args.cases)
    policies = [Path(args.policy)] + ([Path(args.baseline)] if args.baseline else [])
    bags = policy_placements(policies[0], args.placements, args.seed)
    out = Path(args.out or Path(args.policy).parent / f"eval_moving_{int(time.time())}")
    out.mkdir(parents=True, exist_ok=True)
    per_policy = len(bags) * len(cases) * len(args.sigmas)
    evaluations = []
    with tqdm(total=per_policy * len(policies), desc="moving punches (Godot)", unit="punch", disable=not progress) as bar:
        for index, policy in enumerate(policies):
            def advance(done: int, offset: int = index * per_policy) -> None:
                bar.update(offset + done - bar.n)

            rows = run_moving_hits(policy, bags, cases, args.sigmas, args.seed, args.timeout_s, advance, args.lead_s,
                                   args.arms[0])
            evaluations.append({"policy": str(policy), "cases": tally(rows, cases, args.sigmas)})
    report = {"seed": args.seed, "sigmas": args.sigmas, "lead_s": args.lead_s, "arms": list(args.arms[0]),
              "placements": [bag.to_wire() for bag in bags],
              "motion_cases": [asdict(case) for case in cases], "evaluations": evaluations,
              "wall_s": round(time.perf_counter() - started, 1)}
    (out / "moving.json").write_text(json.dumps(report, indent=2) + "\n")
    lines = [f"# punch eval-moving: {args.policy}", "",
             f"{len(bags)} held-out placements (seed {args.seed}), one punch per placement, case and sigma (noise on "
             f"every decision), through PunchController in headless Godot ({report['wall_s']:.0f} s in all); a moving "
             f"character has moved for {args.lead_s:g} s when it punches; arms {size_label(*args.arms[0])} times the "
             "character scene's (upper arm, forearm). A hit: "
             "the controller's `hit` signal on the target during the punch. Cases: docs/moving.md.", "",
             *markdown_table(report)]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out, report
