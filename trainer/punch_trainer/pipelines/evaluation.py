"""`punch eval`: the one evaluator. A scenario (pipelines/scenario.py, docs/evaluation.md) names held-out
placements and the conditions of the punches there; every punch runs in headless Godot through `PunchController`
itself, the node, ONNX Runtime call and noise a game uses, played by one driver (godot_project/tools/evaluate.gd);
one row per condition and sigma, one report (report.md and eval.json in the output directory).

    punch eval --policy P.onnx [--scenario held_out|moving|sizes|FILE.toml] [--baseline OTHER.onnx]
        [--placements 64] [--seed S] [--sigmas 0,0.3] [--conditions NAME ...] [--out DIR]

`punch eval-moving` and `punch eval-sizes` are the scenarios `moving` and `sizes` with their own flags. Per row:
the success rate with its 95% interval (Wilson's: 64 placements tell a few points apart only roughly); with
success "return", the mean return as a fraction of a short search's best at that placement and the spread of the
impact points, and the naturalness figures (docs/naturalness.md) of every condition (the report shows the first's)
beside the captured punches'. This module also holds what `punch replay` and `punch bench inference` share with it: the driver's run
(`run_episodes`), the sigma lists (`parse_sigmas`) and the scoring of recorded punches (`analyse_punches`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.errors import PunchError
from punch_trainer.learn.reach import ReachVolume
from punch_trainer.learn.volume import success, success_interval
from punch_trainer.options import SIGMA, bounds
from punch_trainer.pipelines.scenario import (
    LEAD_MOVES,
    SEED_STRIDE,
    Condition,
    Scenario,
    build_scenario,
    check_arms,
    override,
    read_scenario_data,
    size_label,
)
from punch_trainer.policy_file import read_policy_metadata
from punch_trainer.reward.rewards import Reward, first_right_contact, metadata_reward, score
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.conditions import ARM_SCALE_RANGE, SEGMENT_SCALE_RANGE, EpisodeConditions
from punch_trainer.sim.godot import run_godot_tool

KINDS = ("features", "observations", "mean_actions", "actions")
"""what evaluate.gd records of every punch with --record=1"""


class EvalError(PunchError):
    """An evaluation could not run: bad arguments, a bad policy file, or Godot failed."""


def parse_sigmas(text: str) -> list[float]:
    """`0.1:0.9:0.1` (start:stop:step, inclusive) or `0,0.5`; at most SIGMA.max_items of them (their bounds
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
        raise EvalError(f"bad --sigmas '{text}' (use start:stop:step or a,b,c): {error}") from None


def parse_sizes(text: str) -> list[tuple[float, float]]:
    """`0.7x0.85,1.3x1.1`: upper arm and forearm scales (checked by `check_arms`); a bare `0.8` is both times 0.8."""
    try:
        sizes = [item.split("x") for item in text.split(",") if item.strip()]
        if any(len(size) not in (1, 2) for size in sizes):
            raise ValueError("one or two scales per size")
        return [(float(size[0]), float(size[-1])) for size in sizes]
    except ValueError as error:
        raise EvalError(f"bad --proportions '{text}' (use UPPERxFOREARM,...: 0.7x0.85,1.3x1.1): {error}") from None


def parse_scales(text: str) -> list[float]:
    """`0.75,1,1.25`: arm scales (their range is checked by `check_arms`)."""
    try:
        return [float(value) for value in text.split(",")]
    except ValueError as error:
        raise EvalError(f"bad --scales '{text}' (use a,b,c): {error}") from None


def run_episodes(policy: Path, episodes: list[dict[str, Any]], directory: Path, *, record: bool = False,
                 characters: int = 64, characters_per_world: int = 16, idle_frames: int = 0, timeout_s: float = 3600.0,
                 on_progress: Callable[[int], None] | None = None,
                 timeout_error: Callable[[str], PunchError] = EvalError) -> dict[str, Any]:
    """Plays `episodes` (evaluate.gd's episode objects) for `policy` in headless Godot, writing into `directory`;
    returns evaluate.gd's episodes.json (a row per episode, feature names, inference counts, ...). With `record`,
    `directory` also holds every punch's features, observations and actions (`recorded`)."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "episodes_in.json").write_text(json.dumps(episodes))
    run_godot_tool("evaluate", {"policy": Path(policy).resolve(), "episodes": (directory / "episodes_in.json").resolve(),
                                "out": directory.resolve(), "record": int(record), "characters": characters,
                                "characters-per-world": characters_per_world, "idle-frames": idle_frames},
                   what="the punches", timeout_s=timeout_s, on_progress=on_progress, timeout_error=timeout_error)
    meta: dict[str, Any] = json.loads((directory / "episodes.json").read_text())
    return meta


def recorded(directory: Path, meta: dict[str, Any], kind: str, start: int = 0, count: int | None = None) -> np.ndarray:
    """What `run_episodes(record=True)` recorded of episodes start..start+count: `kind` one of KINDS, as
    [episodes, frames, F] (features) or [episodes, decisions, size]; a memory map (read lazily)."""
    total = int(meta["episodes"])
    rows = np.memmap(directory / f"{kind}.f32", dtype="<f4", mode="r").reshape(total, -1)
    rows = rows[start:total if count is None else start + count]
    return rows.reshape(len(rows), meta["frames"] if kind == "features" else meta["decisions"], -1)


def analyse_punches(features: np.ndarray, names: list[str], reward: Reward, chunk: int = 2000) -> dict[str, Any]:
    """Returns, hits and spreads of a set of punches, features [punches, frames, F] (may be a memmap)."""
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


@dataclass
class EvalArgs:
    policy: Path
    """the policy to measure (an exported .onnx)"""
    scenario: str = "held_out"
    """a shipped scenario's name (held_out, moving, sizes, hands) or a scenario file (.toml; docs/evaluation.md)"""
    baseline: Path | None = None
    """a second policy measured on the same placements and conditions, side by side"""
    reward: str | None = None
    """the reward to score the punches with, a preset or FILE.py:FUNCTION (default: the one the policy's metadata
    names, which must be a preset: a model file never chooses code to run)"""
    placements: int | None = None
    """held-out placements drawn from the reach volume (default: the scenario's)"""
    seed: int | None = None
    """seed of the placements, and of the noise where the scenario names no noise_seed (default: the scenario's, one
    no training stage uses)"""
    sigmas: list[float] | None = None
    """runtime noise sigmas (a,b,c or start:stop:step; default: the scenario's)"""
    noisy_episodes: int | None = field(default=None, metadata=bounds(1, 1000))
    """punches per placement at each sigma > 0 (sigma 0: one; default: the scenario's)"""
    search_iterations: int | None = field(default=None, metadata=bounds(0, 100_000))
    """iterations of the per-placement search (0: no search; fractions of the best are then left out; default: the
    scenario's)"""
    conditions: list[str] | None = None
    """only these of the scenario's conditions, by name (default: all)"""
    arms: list[tuple[float, float]] | None = field(default=None, metadata=bounds(*SEGMENT_SCALE_RANGE, max_items=1))
    """the characters' arms (S, or UPPERxFOREARM), sized through PunchCharacter.size_arms, where a condition sets
    none of its own (default: the scenario's, else the scene's)"""
    scales: list[float] | None = field(default=None, metadata=bounds(*ARM_SCALE_RANGE, max_items=20))
    """arm sizes to measure, one condition each (a,b,c): upper arm and forearm both times the scale, the shoulders as
    they are (default: the scenario's)"""
    proportions: list[tuple[float, float]] | None = field(default=None, metadata=bounds(*SEGMENT_SCALE_RANGE, max_items=20))
    """rigs with other proportions than the scene's (UPPERxFOREARM,...), one condition each, after the scales
    (default: the scenario's)"""
    lead_s: float | None = None
    """how long a moving character has been moving when it punches, s (default: the scenario's)"""
    out: Path | None = None
    """output directory (default: next to the policy, eval_<scenario>_<time>)"""
    timeout_s: float = 3600.0
    """how long Godot may take for one policy's punches"""
    benchmarks: str = ""
    """also write the report's tables as this section of BENCHMARKS.md, with the command and the machine (the one
    results file the docs link to; a section of that name is replaced): a figure is generated, never copied"""


def scenario_of(args: EvalArgs) -> Scenario:
    """The scenario `args` name, with their values over the file's."""
    for upper, forearm in [(s, s) for s in args.scales or []] + list(args.proportions or []) + list(args.arms or []):
        check_arms(upper, forearm, "proportions" if upper != forearm else "arms")
    data, source = read_scenario_data(args.scenario)
    data = override(data, placements=args.placements, seed=args.seed, sigmas=args.sigmas, noisy_punches=args.noisy_episodes,
                    search_iterations=args.search_iterations, lead_s=args.lead_s, arms=args.arms[0] if args.arms else None,
                    conditions=args.conditions, scales=args.scales, proportions=args.proportions)
    return build_scenario(data, source)


@dataclass(frozen=True)
class Group:
    """The punches of one report row: a condition at one sigma, episodes start..start+count of a policy's run."""

    condition: Condition
    sigma: float
    start: int
    count: int


def draw_placements(scenario: Scenario, reach: ReachVolume) -> tuple[list[EpisodeConditions], list[EpisodeConditions]]:
    """The scenario's held-out placements at rest, and their swinging twins (the same places, the bag swinging at
    a speed drawn up to the volume's largest, in a random direction), drawn after them from the same seed."""
    rng = np.random.default_rng(scenario.seed)
    still = reach.sample(rng, scenario.placements)
    if not any(c.swinging for c in scenario.conditions):
        return still, []
    moving = reach.sample(rng, scenario.placements, moving=1.0)
    swinging = [EpisodeConditions.from_wire({**bag.to_wire(), "distance_m": place.distance_m, "height_m": place.height_m,
                                        "side_m": place.side_m}) for bag, place in zip(moving, still, strict=True)]
    return still, swinging


def lead_move_from_stance(condition: Condition, lead_forward_m: float) -> bool:
    """Whether the condition throws a lead hand's move from the stance's guard: its targets lie `lead_forward_m`
    further ahead (docs/moves.md)."""
    return bool(condition.stance_pose and lead_forward_m and condition.move in LEAD_MOVES)


def own_range(condition: Condition, lead_forward_m: float, distance_m: tuple[float, float],
              own_distance_m: tuple[float, float] | None) -> tuple[float, float] | None:
    """The distances a single move is measured over when its policy's reach (`own_distance_m`: a hook's) lies nearer
    than its hand's range and within it; None when the hand's range holds (a combo, a reach that is the hand's or
    lies outside it)."""
    shift = lead_forward_m if lead_move_from_stance(condition, lead_forward_m) else 0.0
    near, far = distance_m[0] + shift, distance_m[1] + shift
    if condition.combo or own_distance_m is None or far <= near:
        return None
    own_near, own_far = own_distance_m
    if (own_near, own_far) == (near, far) or not near - 1e-6 <= own_near <= own_far <= far + 1e-6:
        return None
    return own_near, own_far


def condition_placements(condition: Condition, still: list[EpisodeConditions], swinging: list[EpisodeConditions],
                         lead_forward_m: float, distance_m: tuple[float, float] = (0.0, 0.0),
                         own_distance_m: tuple[float, float] | None = None) -> list[EpisodeConditions]:
    """The placements a condition plays: the swinging twins or the still ones; for a lead hand's move from the
    stance's guard the same moved `lead_forward_m` further ahead (the lead hand's volume: its guard holds the fist that
    much nearer the target; docs/moves.md); for a combination from there with a lead hand's move, drawn into the
    distances both hands reach (the volume's `distance_m` with its near end moved `lead_forward_m` forward). A single
    move whose policy covers nearer distances than its hand's (`own_range`: a hook) is measured over its own: the
    distances drawn into that range."""
    places = swinging if condition.swinging else still
    near, far = distance_m
    if lead_move_from_stance(condition, lead_forward_m):
        places = [dataclasses.replace(bag, distance_m=round(bag.distance_m + lead_forward_m, 6)) for bag in places]
        near, far = near + lead_forward_m, far + lead_forward_m
    elif condition.stance_pose and lead_forward_m and any(move in LEAD_MOVES for move in condition.combo) and far - near > lead_forward_m:
        narrowed = (far - near - lead_forward_m) / (far - near)
        return [dataclasses.replace(bag, distance_m=round(near + lead_forward_m + (bag.distance_m - near) * narrowed, 6))
                for bag in places]
    own = own_range(condition, lead_forward_m, distance_m, own_distance_m)
    if own is None:
        return places
    scale = (own[1] - own[0]) / (far - near)
    return [dataclasses.replace(bag, distance_m=round(own[0] + (bag.distance_m - near) * scale, 6)) for bag in places]


def episodes_of(scenario: Scenario, still: list[EpisodeConditions], swinging: list[EpisodeConditions],
                lead_forward_m: float = 0.0, distance_m: tuple[float, float] = (0.0, 0.0),
                own_distance_m: tuple[float, float] | None = None) -> tuple[list[dict[str, Any]], list[Group]]:
    """evaluate.gd's episodes of a scenario, and the report rows they make. Episode e of sigma index s of a
    condition plays placement e modulo their count with noise seed noise_seed * 1000003 + s * 100003 + e; a lead
    hand's move from the stance's guard plays it `lead_forward_m` further ahead (`condition_placements`)."""
    episodes: list[dict[str, Any]] = []
    groups = []
    for condition in scenario.conditions:
        places = condition_placements(condition, still, swinging, lead_forward_m, distance_m, own_distance_m)
        for index, sigma in enumerate(condition.sigmas):
            count = len(places) * (1 if sigma == 0 else scenario.noisy_punches)
            groups.append(Group(condition, sigma, len(episodes), count))
            for e in range(count):
                bag = places[e % len(places)]
                episode: dict[str, Any] = {
                    "placement": {key: getattr(bag, key) for key in ("distance_m", "height_m", "side_m",
                                                                     "velocity_side_mps", "velocity_forward_mps")},
                    "sigma": sigma, "noise_decisions": condition.noise_decisions,
                    "seed": condition.noise_seed * SEED_STRIDE[0] + index * SEED_STRIDE[1] + e,
                    "start": condition.start, "arms": list(condition.arms), "lead_s": condition.lead_s,
                    "move": condition.move, "stance": condition.stance, "stance_pose": condition.stance_pose,
                    "until_recovered": condition.until_recovered, "guard_first": condition.guard_first,
                    "reset_target": condition.reset_target}
                if condition.combo:
                    episode["combo"] = list(condition.combo)
                if condition.struck is not None:
                    struck = condition.struck
                    episode["struck"] = {"part": struck.part, "impulse_ns": struck.impulse_ns,
                                         "direction": struck.direction(np.random.default_rng(episode["seed"]))}
                if condition.defender is not None:
                    episode["defender"] = {"blocks": condition.defender.blocks, "part": condition.defender.part,
                                           "head_up_m": condition.defender.head_up_m,
                                           "turned_deg": condition.defender.turned_deg}
                    if condition.defender.motion is not None:
                        episode["defender"]["motion"] = condition.defender.motion.to_wire()
                if condition.cancel_delay_s != (0.0, 0.0):
                    low, high = condition.cancel_delay_s
                    episode["cancel_delay_s"] = round(float(np.random.default_rng(episode["seed"]).uniform(low, high)), 4)
                if condition.body is not None:
                    episode["body"] = condition.body.to_wire()
                if condition.target is not None:
                    episode["target"] = condition.target.to_wire()
                episodes.append(episode)
    return episodes, groups


def play_policy(policy: Path, episodes: list[dict[str, Any]], groups: list[Group], reward: Reward | None,
                naturalness: bool, timeout_s: float, on_progress: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Every episode of one policy, and per group what its rows need: the punches' rows, and with `reward` (the
    scenario's success is "return") their returns, success, impact spread and naturalness (every group's); the first group's
    features and actions (for the plots and the search)."""
    from punch_trainer.report.naturalness import punches_naturalness

    record = reward is not None
    physics_hz = float(read_policy_metadata(policy).physics_hz)
    with tempfile.TemporaryDirectory(prefix="punch_eval_") as name:
        directory = Path(name)
        meta = run_episodes(policy, episodes, directory, record=record, timeout_s=timeout_s, on_progress=on_progress)
        names = [str(n) for n in meta["feature_names"]]
        results = []
        for index, group in enumerate(groups):
            rows = meta["rows"][group.start:group.start + group.count]
            result: dict[str, Any] = {"rows": rows, "physics_hz": physics_hz}
            if reward is not None:
                features = np.array(recorded(directory, meta, "features", group.start, group.count))
                analysis = analyse_punches(features, names, reward)
                result.update(returns=analysis["returns"], success=success(analysis["returns"], features, names),
                              impact_spread_m=analysis["impact_spread_m"])
                if naturalness:
                    result["naturalness"] = punches_naturalness(features, names, physics_hz)
                if index == 0:
                    result["features"] = features
                    result["actions"] = np.array(recorded(directory, meta, "actions", group.start, group.count))
            elif group.condition.defender is not None:
                # At a defender: its guard stood in the fist's way first.
                result["success"] = np.array([row[9].get("outcome") == "blocked" for row in rows], dtype=bool)
            elif group.condition.struck is not None:
                # Struck: every body back within 10° of its guard (evaluate.gd's BACK_IN_GUARD_DEG), and `recovered` said so.
                result["success"] = np.array([row[9]["back_s"] >= 0 and row[9]["recovered_s"] >= 0 for row in rows], dtype=bool)
            else:
                # Every punch struck the target (a combo's each once; one punch's at least once).
                needed = max(1, len(group.condition.combo))
                result["success"] = np.array([row[0] >= needed for row in rows], dtype=bool)
            results.append(result)
    return {"groups": results, "feature_names": names, "physics_hz": physics_hz, "arm_scale_range": meta["arm_scale_range"]}


def _play_from_bytes(policy_bytes: bytes, **kwargs: Any) -> dict[str, Any]:
    """`play_policy` on a Ray worker's node, which may not hold the policy file: its bytes travel instead."""
    with tempfile.TemporaryDirectory(prefix="punch_eval_policy_") as directory:
        policy = Path(directory) / "policy.onnx"
        policy.write_bytes(policy_bytes)
        return play_policy(policy, **kwargs)


def search_bests(policy_actions: np.ndarray, bags: list[EpisodeConditions], reward: Reward, smoothing_window: int,
                 iterations: int, seed: int, backend: Backend) -> np.ndarray:
    """The best return a short trajectory search finds at each placement, warm-started from `policy_actions`
    [P, decisions, A] (the policy's own noise-free actions there)."""
    from punch_trainer.learn.search import SearchArgs, placement_search
    from punch_trainer.sim.rollouts import RolloutPool

    args = SearchArgs(reward=reward.name, frames=reward.frames, seed=seed, iterations=iterations, rollouts=16,
                      sigma_init=0.3, smoothing_window=smoothing_window, plateau_iterations=0)
    with RolloutPool(1, 64, backend=backend) as pool:
        results = placement_search(args, reward, pool, progress=False, placements=bags, init_mu=policy_actions, neighbours=0)
    return np.array([r.best_return for r in results])


@dataclass(frozen=True)
class Row:
    """The report's one row type: a condition at one sigma, over every punch of it (eval.json holds them as
    objects, `to_json`)."""

    condition: str
    sigma: float
    punches: int
    successes: int
    """punches that succeeded, as the scenario's `success` counts them"""
    success_rate: float
    success_interval: tuple[float, float]
    """Wilson's 95% score interval of the rate: where the rate at other placements could lie"""
    hits: int
    """punches during which the controller's `hit` signal named the target"""
    out_of_reach: int
    """punches that started with the target outside the policy's reach volume (`target_out_of_reach`)"""
    in_reach_successes: int
    out_of_reach_m: list[float]
    """how far outside the volume the target was, for each of those (m)"""
    moved_m: float
    """how far the moved node (the body, or the target's hook) went, median (m)"""
    arms: str
    """the arms' scales, `S` or `UPPERxFOREARM`"""
    arm_lengths_m: list[float]
    """upper arm, forearm and shoulder width as the sized character reported them, median (m)"""
    missed_placements: list[int]
    """the placements (indices into eval.json's) of the punches that did not succeed"""
    return_fraction_of_search_best: float | None = None
    """success "return": the mean of return / the best known at that placement (None without a search)"""
    impact_spread_m: float | None = None
    """success "return": the mean distance of the first contacts from their mean (m)"""
    contact_s: list[float | None] | None = None
    """per punch (a combo's, in order): the median time from the command to its first contact with the target, over
    the punches that made one (s; a single punch's is its startup)"""
    last_contact_max_s: float | None = None
    """the longest time from the command to the last punch's contact, over the successes (s)"""
    touched_each: list[float] | None = None
    """a combo's: per punch, in order, the share of its combos in which that punch touched the target (which one
    misses where the combo does)"""
    recovery_s: float | None = None
    """`until_recovered`: the median time from the last punch's contact to `recovered` (s)"""
    struck: dict[str, Any] | None = None
    """a struck character's (`struck_figures`): how far its bodies turned and its head moved, when it was back"""
    defended: dict[str, Any] | None = None
    """at a defender (`defended_figures`): what the punches became, and how often and how hard they reached its head"""

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "success_interval": list(self.success_interval)}


def make_row(group: Group, result: dict[str, Any], placements: int, best: np.ndarray | None) -> Row:
    """The row of one group's punches (`play_policy`'s result for it; evaluate.gd's row of a punch: hits,
    out-of-reach signals, metres out of reach, how it ended, metres moved, upper arm, forearm, shoulders)."""
    rows, won = result["rows"], result["success"]
    placement = np.arange(group.count) % placements
    in_reach = [i for i, row in enumerate(rows) if row[1] == 0]
    lengths = np.median(np.array([row[5:8] for row in rows], dtype=float), axis=0)
    fraction = None
    if best is not None and "returns" in result:
        scored = best[placement] > 0  # a placement where nothing scores has no fraction
        fraction = float(np.mean(result["returns"][scored] / best[placement][scored])) if scored.any() else None
    return Row(condition=group.condition.name, sigma=group.sigma, punches=group.count, successes=int(won.sum()),
               success_rate=float(won.mean()), success_interval=success_interval(int(won.sum()), group.count),
               hits=sum(1 for row in rows if row[0] > 0), out_of_reach=group.count - len(in_reach),
               in_reach_successes=int(sum(won[i] for i in in_reach)),
               out_of_reach_m=sorted(float(row[2]) for row in rows if row[1] > 0),
               moved_m=float(np.median([float(row[4]) for row in rows])), arms=size_label(*group.condition.arms),
               arm_lengths_m=[round(float(v), 4) for v in lengths],
               missed_placements=sorted({int(p) for p, ok in zip(placement, won, strict=True) if not ok}),
               return_fraction_of_search_best=fraction, impact_spread_m=result.get("impact_spread_m"),
               **timing_figures(group, rows, won, float(result["physics_hz"])),
               struck=struck_figures(rows) if group.condition.struck is not None else None,
               defended=defended_figures(rows) if group.condition.defender is not None else None)


def defended_figures(rows: list[list[Any]]) -> dict[str, Any]:
    """A defender's figures over its episodes (evaluate.gd's per-episode entry): how many punches `landed`, were
    `blocked` and `whiffed` (`punch_finished`'s outcome), how many reached the part aimed at (head or torso) at all
    (first or after an arm), and the mean impulse of the fist's first frame on it over all the punches (N s; 0 for one
    that never reached it)."""
    entries = [row[9] for row in rows]
    outcomes = [entry.get("outcome", "") for entry in entries]
    head = [float(entry.get("head_impulse_ns", 0.0)) for entry in entries]
    return {"landed": outcomes.count("landed"), "blocked": outcomes.count("blocked"), "whiffed": outcomes.count("whiffed"),
            "head_reached": sum(1 for entry in entries if "head_impulse_ns" in entry),
            "head_impulse_ns_mean": round(float(np.mean(head)), 3) if head else 0.0}


def struck_figures(rows: list[list[Any]]) -> dict[str, Any]:
    """A struck character's figures over its episodes (evaluate.gd's per-episode `struck` entry): the largest turn of
    any body from its guard (degrees) and the head's largest move (m), medians; the time from the hit until every body
    was back within 10° of its guard (evaluate.gd's BACK_IN_GUARD_DEG), median and longest, and until `recovered`, median (s; a body that
    never left counts 0); how many episodes staggered and were knocked down."""
    struck = [row[9] for row in rows]
    back = [s["back_s"] for s in struck if s["back_s"] >= 0]
    recovered = [s["recovered_s"] for s in struck if s["recovered_s"] >= 0]
    return {"peak_turn_deg": round(float(np.median([s["peak_deg"] for s in struck])), 1),
            "head_moved_m": round(float(np.median([s["head_moved_m"] for s in struck])), 3),
            "back_in_guard_s": [round(float(np.median(back)), 3), round(max(back), 3)] if back else None,
            "recovered_s": round(float(np.median(recovered)), 3) if recovered else None,
            "staggered": sum(1 for s in struck if s["staggered"]), "knocked_down": sum(1 for s in struck if s["knocked_down"])}


def timing_figures(group: Group, rows: list[list[Any]], won: np.ndarray, physics_hz: float) -> dict[str, Any]:
    """`Row.contact_s`, `last_contact_max_s` and `recovery_s` from evaluate.gd's timings (physics frames from the
    command: per punch [started, first contact or -1], then `recovered` with `until_recovered`)."""
    punches = max(1, len(group.condition.combo))
    timings = [row[8] for row in rows]
    contacts = [[t[i][1] for t in timings if len(t) > i and isinstance(t[i], list) and t[i][1] >= 0] for i in range(punches)]
    last = [t[punches - 1][1] for t, ok in zip(timings, won, strict=True) if ok and len(t) >= punches and isinstance(t[punches - 1], list)]
    figures: dict[str, Any] = {
        "contact_s": [round(float(np.median(c)) / physics_hz, 4) if c else None for c in contacts],
        "last_contact_max_s": round(max(last) / physics_hz, 4) if last else None}
    if group.condition.combo:
        figures["touched_each"] = [round(len(c) / max(1, len(timings)), 4) for c in contacts]
    if group.condition.until_recovered:
        back = [t[-1] - t[-2][1] for t in timings if len(t) > punches and t[-1] >= 0 and t[-2][1] >= 0]
        figures["recovery_s"] = round(float(np.median(back)) / physics_hz, 4) if back else None
    return figures


def run_eval(args: EvalArgs, progress: bool = True, *, backend: Backend = LOCAL) -> tuple[Path, dict[str, Any]]:
    """The whole `punch eval` command (and its shortcuts), every punch and search on `backend`: writes eval.json
    and report.md in the output directory."""
    started = time.perf_counter()
    scenario = scenario_of(args)
    policies = [Path(args.policy)] + ([Path(args.baseline)] if args.baseline else [])
    metadata = [read_policy_metadata(policy) for policy in policies]
    reward = None
    if scenario.success == "return":
        rewards = [metadata_reward(m.entries, str(p), args.reward) for m, p in zip(metadata, policies, strict=True)]
        if any(r.name != rewards[0].name for r in rewards):
            raise EvalError("--baseline must be trained for the same reward as --policy")
        reward = rewards[0]
    lead_forward_m = 0.0  # a policy's own volume is its hand's already
    if scenario.volume == "spec":
        from punch_trainer.sim.rollouts import RolloutPool

        with RolloutPool(1, 1, backend=backend) as pool:
            reach = ReachVolume.from_json(pool.info.reach_volume)
            lead_forward_m = pool.info.stance_lead_forward_m
    else:
        reach = ReachVolume.from_json(metadata[0].reach_volume)
    if scenario.distance_m is not None:
        reach = dataclasses.replace(reach, distance_m=scenario.distance_m)
    if scenario.height_m is not None:
        reach = dataclasses.replace(reach, height_m=scenario.height_m)
    if scenario.side_m is not None:
        reach = dataclasses.replace(reach, side_m=scenario.side_m)
    still, swinging = draw_placements(scenario, reach)
    own_distance_m = ReachVolume.from_json(metadata[0].reach_volume).distance_m
    episodes, groups = episodes_of(scenario, still, swinging, lead_forward_m, reach.distance_m, own_distance_m)
    out = Path(args.out or Path(args.policy).parent / f"eval_{scenario.name}_{int(time.time())}")
    out.mkdir(parents=True, exist_ok=True)
    calls: list[dict[str, Any]] = [{"episodes": episodes, "groups": groups, "reward": reward, "naturalness": scenario.naturalness,
              "timeout_s": args.timeout_s} for _ in policies]
    if backend.shares_files:
        with tqdm(total=len(episodes) * len(policies), desc=f"{scenario.name} punches (Godot)", unit="punch",
                  disable=not progress) as bar:
            runs = []
            for index, (policy, call) in enumerate(zip(policies, calls, strict=True)):
                def advance(done: int, offset: int = index * len(episodes)) -> None:
                    bar.update(offset + done - bar.n)

                runs.append(play_policy(policy, **call, on_progress=advance))
    else:
        runs = backend.map(_play_from_bytes, [{"policy_bytes": policy.read_bytes(), **call} for policy, call in zip(policies, calls, strict=True)])
    best = None
    if reward is not None and scenario.search_iterations > 0:
        if progress:
            print("searching the best punch at every placement ...", flush=True)
        searched = condition_placements(groups[0].condition, still, [], lead_forward_m, reach.distance_m, own_distance_m)
        best = search_bests(runs[0]["groups"][0]["actions"], searched, reward, metadata[0].smoothing_window,
                            scenario.search_iterations, scenario.seed, backend)
        best = np.max([best, *[run["groups"][0]["returns"] for run in runs]], axis=0)  # a policy may beat the short search
    evaluations = [evaluation_of(policy, run, groups, scenario, reward, best) for policy, run in zip(policies, runs, strict=True)]
    capture = None
    if scenario.naturalness and reward is not None:
        from punch_trainer.report.naturalness import capture_figures

        capture = capture_figures()
    report = {"scenario": scenario.to_json(), "seed": scenario.seed, "placements": [bag.to_wire() for bag in still],
              "swinging_placements": [bag.to_wire() for bag in swinging], "reach": json.loads(reach.to_json()),
              "lead_forward_m": lead_forward_m,
              "own_distance_m": list(own_distance_m) if any(own_range(c, lead_forward_m, reach.distance_m, own_distance_m)
                                                            for c in scenario.conditions) else None,
              "arm_scale_range": runs[0]["arm_scale_range"], "search_best": best.tolist() if best is not None else None,
              "evaluations": evaluations,
              "captured_naturalness": [punch.to_json() for punch in capture] if capture else None,
              "wall_s": round(time.perf_counter() - started, 1)}
    (out / "eval.json").write_text(json.dumps(report, indent=2) + "\n")
    write_report(out, args, scenario, report, runs, still, capture)
    return out, report


def evaluation_of(policy: Path, run: dict[str, Any], groups: list[Group], scenario: Scenario, reward: Reward | None,
                  best: np.ndarray | None) -> dict[str, Any]:
    """One policy's part of the report: its rows, and what the plots and naturalness tables read."""
    from punch_trainer.report.naturalness import summarise

    rows = [make_row(group, result, scenario.placements, best).to_json() for group, result in zip(groups, run["groups"], strict=True)]
    first = run["groups"][0]
    evaluation: dict[str, Any] = {"policy": str(policy), "reward": reward.name if reward else None, "rows": rows,
                                  "success_at_sigma0": first["success"][:scenario.placements].tolist()}
    if "naturalness" in first:
        evaluation["naturalness"] = [{"condition": group.condition.name, "sigma": group.sigma, **summarise(result["naturalness"]).to_json()}
                                     for group, result in zip(groups, run["groups"], strict=True) if "naturalness" in result]
        evaluation["naturalness_at_sigma0"] = [punch.to_json() for punch in first["naturalness"]]
    return evaluation


def markdown_rows(scenario: Scenario, rows: list[dict[str, Any]]) -> list[str]:
    """The report's table of one policy (its `Row`s, as eval.json holds them): a line per condition and sigma; the columns a scenario has no use for
    (a search's fraction, an impact spread, arm lengths, how far the body moved, targets out of reach) left out."""
    returns = scenario.success == "return"
    sized = any(c.arms != (1.0, 1.0) for c in scenario.conditions)
    moves = any(c.moves() for c in scenario.conditions)
    reach = any(row["out_of_reach"] for row in rows)
    timed = any(c.combo or c.until_recovered for c in scenario.conditions)
    recovering = any(c.until_recovered for c in scenario.conditions)
    header = ["condition", "sigma", "punches", "success", "its 95% interval"]
    header += ["return / best known", "impact spread (cm)"] if returns else []
    header += ["upper arm / forearm / shoulders (m)"] if sized else []
    header += ["moved (m)"] if moves else []
    header += ["out of reach at the start (successes in reach)"] if reach else []
    header += ["contact after the command, each punch (s, median)", "last contact, longest (s)"] if timed else []
    combos = any(c.combo for c in scenario.conditions)
    header += ["touched the target, each punch"] if combos else []
    header += ["contact to back in guard (s, median)"] if recovering else []
    struck = any(c.struck for c in scenario.conditions)
    header += ["largest turn of a body (°, median)", "head moved (cm, median)", "back within 10° of guard (s, median / longest)",
               "recovered (s, median)", "staggered / knocked down"] if struck else []
    defended = any(c.defender for c in scenario.conditions)
    header += ["landed / blocked / whiffed", "fist reached the part aimed at", "on it, first frame (N s, mean)"] if defended else []
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        low, high = row["success_interval"]
        cells = [row["condition"], f"{row['sigma']:.2f}", str(row["punches"]), f"{row['successes']} ({100 * row['success_rate']:.1f}%)",
                 f"{100 * low:.1f}-{100 * high:.1f}%"]
        if returns:
            fraction = row["return_fraction_of_search_best"]
            cells += [f"{fraction:.2f}" if fraction is not None else "-", f"{100 * row['impact_spread_m']:.1f}"]
        if sized:
            cells.append(" / ".join(f"{v:.3f}" for v in row["arm_lengths_m"]))
        if moves:
            cells.append(f"{row['moved_m']:.2f}")
        if reach:
            cells.append(f"{row['out_of_reach']} ({row['in_reach_successes']}/{row['punches'] - row['out_of_reach']})"
                         if row["out_of_reach"] else "-")
        if timed:
            cells += [" / ".join(_seconds(v) for v in row.get("contact_s") or []) or "-", _seconds(row.get("last_contact_max_s"))]
        if combos:
            cells.append(" / ".join(f"{100 * share:.0f}%" for share in row.get("touched_each") or []) or "-")
        if recovering:
            cells.append(f"{row['recovery_s']:.2f}" if row.get("recovery_s") is not None else "-")
        if struck:
            figures = row.get("struck") or {}
            back = figures.get("back_in_guard_s")
            cells += [f"{figures['peak_turn_deg']:.1f}", f"{100 * figures['head_moved_m']:.1f}",
                      f"{back[0]:.2f} / {back[1]:.2f}" if back else "-", _seconds(figures.get("recovered_s")),
                      f"{figures['staggered']} / {figures['knocked_down']}"] if figures else ["-"] * 5
        if defended:
            figures = row.get("defended") or {}
            cells += [f"{figures['landed']} / {figures['blocked']} / {figures['whiffed']}", str(figures["head_reached"]),
                      f"{figures['head_impulse_ns_mean']:.2f}"] if figures else ["-"] * 3
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _seconds(value: float | None) -> str:
    return f"{value:.2f}" if value is not None else "-"


def benchmarks_body(report_md: str, depth: int = 1) -> list[str]:
    """A report.md as a BENCHMARKS.md section holds it: the tables and their explanation, its headings `depth` levels
    down, without its title and plots (they stay with the run)."""
    return [("#" * depth + line if line.startswith("## ") else line) for line in report_md.splitlines()[1:] if not line.startswith("![")]


def write_report(out: Path, args: EvalArgs, scenario: Scenario, report: dict[str, Any], runs: list[dict[str, Any]],
                 still: list[EpisodeConditions], capture: Any) -> None:
    from punch_trainer.report.naturalness import NaturalnessSummary, naturalness_table
    from punch_trainer.report.plots import plot_eval

    measured = ("a positive return (the policy's reward) and the right fist touched the target"
                if scenario.success == "return" else "the controller's `hit` signal on the target during the punch")
    if any(c.struck for c in scenario.conditions):
        measured += (" (a struck character's, which throws no punch: every body back within 10° of its guard, and "
                     "`recovered`)")
    if any(c.defender for c in scenario.conditions):
        measured = ("at a defender (a second character standing in the bag's place, its root at the placement, the punch "
                    "aimed at its head or torso): the punch's `punch_finished` outcome `blocked`, its fist's first "
                    "contact on the defender's arm")
    lead_forward_m = report.get("lead_forward_m", 0.0)
    lines = [f"# punch eval: {args.policy}", "",
             f"Scenario `{scenario.name}` ({scenario.source}): {scenario.description}.", "",
             f"{scenario.placements} held-out placements drawn from the {scenario.volume}'s reach volume"
             + (f" at distances {scenario.distance_m[0]:g}-{scenario.distance_m[1]:g} m" if scenario.distance_m else "")
             + (f" at heights {scenario.height_m[0]:g}-{scenario.height_m[1]:g} m" if scenario.height_m else "")
             + (f" (a lead hand's move from the stance's guard: each {lead_forward_m:g} m further ahead, as its guard holds "
                "the fist that much nearer; a combination from there with a lead hand's move: at the distances both "
                "hands reach)" if lead_forward_m and any(c.stance_pose and (c.move in LEAD_MOVES or c.combo)
                                                         for c in scenario.conditions) else "")
             + (f" (the policy's own reach is nearer than its hand's: its targets drawn into {own[0]:g}-{own[1]:g} m ahead)"
                if (own := report.get("own_distance_m")) else "")
             + " with seed "
             f"{scenario.seed} (a seed no training stage uses); one punch per placement and condition at "
             f"sigma 0, {scenario.noisy_punches} at each sigma above it; every punch through PunchController in headless "
             f"Godot ({report['wall_s']:.0f} s in all). Success: {measured}; its interval: Wilson's 95% score interval, "
             "where the rate at other placements could lie."]
    if scenario.success == "return":
        lines += ["", f"Return: the mean of return / the best return known at that placement (a {scenario.search_iterations}-"
                  "iteration search warm-started from the first policy's punch, or a policy's own noise-free punch if "
                  "better); placements where nothing scores are left out."]
    lines.append("")
    for index, evaluation in enumerate(report["evaluations"]):
        lines += [f"## {evaluation['policy']}" + (f" (reward `{evaluation['reward']}`)" if evaluation["reward"] else ""), "",
                  *markdown_rows(scenario, evaluation["rows"]), ""]
        if "naturalness" in evaluation:
            lines += [f"Naturalness (docs/naturalness.md): medians over the punches of `{scenario.conditions[0].name}`; the "
                      "captured punches' range from movement onset to full reach.", ""]
            lines += naturalness_table([(f"sigma {row['sigma']:g}", NaturalnessSummary.from_json(row))
                                        for row in evaluation["naturalness"] if row["condition"] == scenario.conditions[0].name], capture)
            first = runs[index]["groups"][0]
            plots = plot_naturalness(out, first["features"], runs[index]["feature_names"], runs[index]["physics_hz"], still,
                                     "" if index == 0 else "_baseline")
            lines += ["", *[f"![{p.stem}]({p.name})" for p in plots], ""]
    lines += [f"![{p.stem}]({p.name})" for p in plot_eval(out, report["placements"], report["evaluations"])]
    (out / "report.md").write_text("\n".join(lines) + "\n")


def plot_naturalness(out: Path, features: np.ndarray, names: list[str], physics_hz: float, placements: list[EpisodeConditions],
                     suffix: str = "") -> list[Path]:
    """Fig. 4 of a policy's punches (`features`, one per placement) against the capture, and the stick-figure strip
    of its punch at the placement nearest the middle of `placements`."""
    from punch_trainer.capture.bvh import DEFAULT_BVH
    from punch_trainer.capture.punches import captured_punches
    from punch_trainer.report.naturalness_plots import plot_capture_comparison, plot_stick_strip

    capture = captured_punches(DEFAULT_BVH)
    points = np.array([[p.distance_m, p.height_m, p.side_m] for p in placements])
    spread = np.where(points.std(axis=0) > 0, points.std(axis=0), 1.0)
    middle = int(np.argmin(np.linalg.norm((points - points.mean(axis=0)) / spread, axis=1)))
    return [plot_capture_comparison(out, features, names, physics_hz, capture, file_name=f"naturalness_fig4{suffix}.png"),
            plot_stick_strip(out, features[middle], names, physics_hz, capture[0], file_name=f"naturalness_strip{suffix}.png")]
