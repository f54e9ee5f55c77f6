"""`punch train`: the whole pipeline for one reward. Trajectory search, then the dataset, supervised
pretraining, A2C, and export to ONNX, ending with a noise-free run of the exported policy in the
simulator. Everything goes into one run directory with a short report.

By default the policy covers the spec's reach volume (`punch_trainer.learn.volume`: a search at a grid of
placements warm-started from the default one, all best trajectories in the dataset, A2C over random
placements, swinging bags and starts after earlier punches). `--reach spot` trains at the default placement
only, as the paper does: the quickstart, in seconds, and a policy that hits only there."""

from __future__ import annotations

import dataclasses
import functools
import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import onnxruntime

from punch_trainer.learn.a2c import A2CArgs, evaluate_noise_free, train_a2c
from punch_trainer.learn.checkpoint import CONFIG_FILE, CheckpointError, default_run_dir, load_checkpoint, save_checkpoint, write_config
from punch_trainer.learn.dataset import load_datasets, record_datasets
from punch_trainer.learn.export import export_policy
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.pretrain import PretrainArgs, fit_critic, pretrain
from punch_trainer.learn.reach import ReachVolume
from punch_trainer.learn.search import SearchArgs, SearchResult, placement_search
from punch_trainer.learn.volume import (
    ArmRange,
    ConditionSampler,
    MotionRange,
    VolumeArgs,
    distribution_observations,
    holding,
    validate,
)
from punch_trainer.learn.warm_start import SNAPSHOT_KIND, check_source, warm_start
from punch_trainer.options import bounds
from punch_trainer.pipelines.search import run_search
from punch_trainer.policy_file import SPEC_HASH, START_LOAD
from punch_trainer.report.a2c_report import write_a2c_report
from punch_trainer.report.motion import motion_report
from punch_trainer.report.naturalness import capture_figures, naturalness_table, punch_naturalness, summarise
from punch_trainer.reward.rewards import EpisodeScorer, Reward, load_reward
from punch_trainer.reward.style import DEFAULT_STYLE, style_label, style_named
from punch_trainer.reward.style import MAX_WEIGHT as MAX_STYLE_WEIGHT
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.conditions import ARM_SCALE_RANGE, EpisodeConditions, EpisodeStart
from punch_trainer.sim.env import PunchVectorEnv
from punch_trainer.sim.mirror import VectorMirror
from punch_trainer.sim.rollouts import RolloutPool
from punch_trainer.sim.server import ServerInfo
from punch_trainer.sim.server_group import SimulatorRestarts


@dataclass(frozen=True)
class ReachDefaults:
    """The settings whose default depends on `--reach` (a TrainArgs field of None takes the one here)."""

    a2c_updates: int
    a2c_time_budget_s: float
    a2c_sigma_floor: float
    a2c_processes: int
    """Godot processes of `a2c_characters` each for A2C"""
    pretrain_initial_sigma: float


REACH_DEFAULTS = {
    # Over the volume: updates enough that the time budget decides; sigma at least 0.2, so that the policy keeps
    # meeting noisy decisions and learns to recover from them (BENCHMARKS.md).
    "volume": ReachDefaults(a2c_updates=5000, a2c_time_budget_s=600.0, a2c_sigma_floor=0.2, a2c_processes=2, pretrain_initial_sigma=0.3),
    "spot": ReachDefaults(a2c_updates=40, a2c_time_budget_s=60.0, a2c_sigma_floor=0.0, a2c_processes=1, pretrain_initial_sigma=0.1),
}


def reach_default_notes() -> dict[str, str]:
    """What a TrainArgs field of None stands for, for `--help`."""
    volume, spot = REACH_DEFAULTS["volume"], REACH_DEFAULTS["spot"]
    return {name: f"{getattr(volume, name):g} over the volume, {getattr(spot, name):g} at a spot"
            for name in ("a2c_updates", "a2c_time_budget_s", "a2c_sigma_floor")}


@dataclass
class TrainArgs:
    reward: str = SearchArgs.reward
    """a preset (the paper's straight, straight100, hook and swing, and the moves' rewards: README, "Training your own
    punch") or FILE.py:FUNCTION"""
    style: str = DEFAULT_STYLE
    """the motion style added to the reward in every stage (docs/style.md): boxing, a human's punch; none, the reward
    alone (the paper's); or FILE.toml:NAME, a style of a file (recipes/styles.toml: the shipped policies')"""
    style_weight: float = field(default=SearchArgs.style_weight, metadata=bounds(0.0, MAX_STYLE_WEIGHT))
    """how strongly the style holds (1: as measured in docs/style.md)"""
    frames: int | None = None
    """episode length in physics frames (default: the reward's)"""
    seed: int = 0
    """seed of every stage (A2C's episode conditions draw from seed + 1, its validation placements from seed + 2)"""
    out: Path | None = None
    """run directory (default runs/train_<reward>__<seed>__<time>)"""
    search_iterations: int = 100
    """most iterations of the search at the default placement"""
    search_rollouts: int = SearchArgs.rollouts
    """sampled trajectories per iteration of the search at the default placement"""
    smoothing_window: int = SearchArgs.smoothing_window
    """Eq. 1 window n of the search, the datasets and A2C (1: no smoothing)"""
    pretrain_epochs: int = PretrainArgs.epochs
    """supervised pretraining epochs on the datasets"""
    a2c_updates: int | None = None
    """A2C updates, each one episode on every character"""
    a2c_characters: int = A2CArgs.characters
    """characters per A2C process"""
    advantage: Literal["gae", "paper"] = "gae"
    """A2C's advantage estimate: 'gae', or 'paper' (the paper's formula as printed)"""
    a2c_sigma_floor: float | None = None
    """the least sigma A2C samples actions with"""
    a2c_time_budget_s: float | None = None
    """stop A2C after this much wall time (0: no limit, which makes a run reproducible)"""
    a2c_snapshot_every: int = 0
    """also export the policy as A2C has it every this many updates, to a2c/snapshots/update_<N>/policy.onnx (0: none):
    A2C keeps the parameters with the best return on its validation placements, which need not be the ones that hit
    most often at a weak spot; `punch eval-sizes` or `punch eval` on the snapshots tells (policies/README.md)"""
    reach: Literal["volume", "spot"] = "volume"
    """'volume': every target placement of the spec's reach volume (docs/env.md), minutes; 'spot': the default
    placement only, seconds (the quickstart; the policy hits only there)"""
    grid: str = ",".join(map(str, VolumeArgs.grid))
    """volume: search placements along distance,height,side"""
    volume_search_iterations: int = VolumeArgs.search_iterations
    """volume: most iterations of the search over the grid"""
    volume_search_rollouts: int = VolumeArgs.search_rollouts
    """volume: rollouts per placement and iteration"""
    default_share: float = VolumeArgs.default_share
    """volume: share of A2C episodes with the bag at the default placement"""
    search_stances: bool = False
    """volume: also search over the grid from each stance's guard (orthodox and southpaw, after a lead-in holding it)
    and pretrain on those punches too: the start a policy needs for `--stance-share` (a rear uppercut from the
    orthodox guard is found by the search, never by A2C alone: experiments/notebook.md)"""
    stance_share: float = VolumeArgs.stance_share
    """volume: share of A2C episodes (and validation placements) that start in a boxing stance's guard, orthodox or
    southpaw (`PunchController.stance_pose`); the others start in the square guard"""
    guard: Literal["square", "orthodox", "southpaw"] = "square"
    """volume: the guard every punch of the policy starts from. 'orthodox' trains a rear hand's move (the right hand
    from the orthodox guard), 'southpaw' a lead hand's (the right hand leading, over the volume moved forward by the
    server's `stance_lead_forward_m`: its guard holds the fist that much nearer); the game mirrors either for the other
    stance (docs/moves.md). The volume search, its datasets, A2C's episodes and its validation all start there, after
    a lead-in holding it: one start, so that pretraining keeps what the search found there (experiments/notebook.md,
    "A policy for each hand's guard")"""
    load: Literal["hook", "uppercut"] | None = None
    """volume: with --guard orthodox or southpaw, every punch starts with the punching arm drawn from that guard into
    a move's load (the server's `loaded_guard_actions`, punch_core's `stance::Load`): the hook's elbow raised out to
    the side, the uppercut's fist dropped to the chest, room for the lead hand's hook to sweep and its uppercut to rise;
    the policy file says so (`punch_start_load`) and the game draws the arm there before the policy starts
    (docs/moves.md)"""
    reach_distance: list[float] | None = field(default=None, metadata=bounds(0.3, 1.5, max_items=2))
    """volume: NEAR FAR, how far ahead of the root the targets' centres lie (m), instead of the volume's (which `--guard
    southpaw` moves forward): a move thrown closer than a straight, as a hook with its elbow bent (recipes/rear_hook.toml);
    the policy's reach says so (a game aims at a target up to 0.3 m beyond it, and at that far point beyond)"""
    reach_height: list[float] | None = field(default=None, metadata=bounds(0.5, 2.0, max_items=2))
    """volume: LOW HIGH, how high the targets' centres lie (m), instead of the volume's 1.15-1.55: a move thrown at
    the head and the body alike, as an uppercut (experiments/notebook.md, "An uppercut that rises with the elbow
    bent"; the body band is 1.00-1.20 m)"""
    lead_in_every: int = VolumeArgs.lead_in_every
    """volume: every k-th A2C update's episodes start where an earlier punch of this run's search left the arms (at its
    contact, drawing back, or on the way back to guard) instead of in a guard: a policy for punches started wherever
    the arms are (`PunchController.guard_first` off, a combo's next punch); 0: never"""
    lead_in_policies: list[Path] | None = field(default=None, metadata=bounds(max_items=8))
    """volume, with --lead-in-every: policy files (the other moves) whose punches the lead-ins replay too, each with
    either hand (the arm this policy punches with, and the other, mirrored): so a move learns to start where a
    combo's earlier move leaves the arms, not only where its own does"""
    motions: Literal["move", "stand"] = "move"
    """volume: 'move': A2C's characters walk, turn, lunge and bob while they punch and targets are carried past
    them (docs/moving.md), and so do half the validation placements; 'stand': every character stands still"""
    arms: Literal["sized", "scene"] = "sized"
    """volume: 'sized': A2C's characters have arms of the sizes a rig may have (`PunchCharacter.size_arms`,
    README, "Your own character"), and so do some validation placements; 'scene': every character has the scene's"""
    arm_range: list[float] = field(default_factory=lambda: list(ARM_SCALE_RANGE),
                                   metadata=bounds(*ARM_SCALE_RANGE, max_items=2))
    """volume, with --arms sized: LOW HIGH, the arms' scales (shoulder to fist, times the scene's) A2C draws from,
    within what `size_arms` accepts: narrow it to the characters of a game"""
    init_from: Path | None = None
    """an earlier `punch train` run (its folder) whose best policy A2C starts from instead of a pretraining on this
    run's search, one of its snapshots (RUN/a2c/snapshots/update_<N>), or a policy file of this observation spec
    (such as addons/punch_controller/policies/hook.onnx; its critic is fitted to this run's search): to train a
    policy further, or for a policy contract that added inputs (they start at zero weight; learn/warm_start.py)"""
    processes: int = SearchArgs.processes
    """Godot processes (with --ray: Ray workers, docs/cluster.md) of 64 characters for the searches"""

    def run_dir(self) -> Path:
        """`out`, or a new runs/train_<reward>__<seed>__<time>."""
        return self.out or default_run_dir(f"train_{self.reward}", self.seed)


def run_exported_policy(path: Path, env: PunchVectorEnv, reward: Reward, sigma: float = 0.0,
                        seed: int = 0, start: EpisodeStart | None = None) -> tuple[float, np.ndarray]:
    """Runs an exported policy file with onnxruntime in the simulator (noise `sigma` on its mean), from `start`
    (default: the square guard, the default placement); returns character 0's return and its features [frames, F]."""
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(options=start)
    total_return, frames, scorer = 0.0, [], EpisodeScorer(reward, env.feature_names)
    while True:
        mean, _ = session.run(None, {"obs": obs.astype(np.float32)})
        action = np.clip(mean + sigma * rng.standard_normal(mean.shape), -1, 1).astype(np.float32)
        obs, _, terminated, truncated, info = env.step(action)
        total_return += float(scorer.add(info["features"][:1])[0][0])
        frames.append(info["features"][0])
        if terminated[0] or truncated[0]:
            return total_return, np.concatenate(frames)


def other_moves_punches(policies: list[Path], reach: ReachVolume, decisions: int, mirror: VectorMirror, seed: int,
                        placements: int = 64, sigma: float = 0.2) -> np.ndarray:
    """Raw actions [2 * placements * len(policies), decisions, A]: each policy file punching at `placements` of the
    reach volume with a designer's noise `sigma`, through PunchController in headless Godot, and the mirror image of
    each (the same punch by the other arm). Cut to `decisions`, or held in guard (zeros) after a shorter punch."""
    from punch_trainer.pipelines.evaluation import recorded, run_episodes

    bags = reach.sample(np.random.default_rng([seed, 7]), placements)
    episodes = [{"placement": {"distance_m": bag.distance_m, "height_m": bag.height_m, "side_m": bag.side_m},
                 "sigma": sigma, "seed": seed * 1000 + index} for index, bag in enumerate(bags)]
    punches = []
    for policy in policies:
        if not Path(policy).is_file():
            raise FileNotFoundError(f"--lead-in-policies: no policy file {policy}")
        with tempfile.TemporaryDirectory(prefix="punch_lead_ins_") as name:
            meta = run_episodes(Path(policy), episodes, Path(name), record=True)
            actions = np.array(recorded(Path(name), meta, "actions"), dtype=np.float32)
        fitted = np.zeros((len(actions), decisions, actions.shape[2]), dtype=np.float32)
        fitted[:, :min(decisions, actions.shape[1])] = actions[:, :decisions]
        punches += [fitted, mirror(fitted).astype(np.float32)]
    return np.concatenate(punches)


def parse_grid(text: str) -> tuple[int, int, int]:
    """`3,3,3`: search placements along distance, height and side."""
    try:
        distance, height, side = (int(v) for v in text.split(","))
    except ValueError:
        distance = height = side = 0
    if min(distance, height, side) < 1:
        raise ValueError(f"--grid is three counts >= 1 (distance,height,side), not '{text}'")
    return distance, height, side


def lead_forward_m(args: TrainArgs, info: ServerInfo) -> float:
    """How much further forward than the spec's volume the policy's targets lie (m): a lead hand's move (`--guard
    southpaw`) punches from a guard that holds its fist nearer the target, so it covers the volume moved forward by
    the server's `stance_lead_forward_m` (docs/moves.md); 0 for every other guard."""
    return info.stance_lead_forward_m if args.guard == "southpaw" else 0.0


def policy_reach(args: TrainArgs, info: ServerInfo) -> ReachVolume:
    """The target placements the policy covers: the server's volume, moved forward for a lead hand's move
    (`lead_forward_m`), its distances and heights replaced by `--reach-distance` and `--reach-height` when given."""
    reach = ReachVolume.from_json(info.reach_volume).moved_forward(lead_forward_m(args, info))
    if args.reach_distance is not None:
        reach = dataclasses.replace(reach, distance_m=(args.reach_distance[0], args.reach_distance[1]))
    if args.reach_height is not None:
        reach = dataclasses.replace(reach, height_m=(args.reach_height[0], args.reach_height[1]))
    return reach


def search_volume(args: TrainArgs, volume: VolumeArgs, reward: Reward, centre: SearchResult, progress: bool,
                  resume: bool, backend: Backend) -> tuple[list[Path], ReachVolume, list[float], np.ndarray]:
    """The search over the reach volume's grid, warm-started from the default placement's best (`centre`),
    and one dataset per placement in volume_search/datasets/; with `args.search_stances`, the same from each stance's
    guard too (volume_search_orthodox/, volume_search_southpaw/: every rollout after a lead-in holding it). Returns
    the dataset paths (every start's), the reach, each placement's best return and best actions [P, decisions, A]
    (the first start's: the square guard's, or `args.guard`'s alone)."""
    starts = [args.guard] if args.guard != "square" else ["square", *(["orthodox", "southpaw"] if args.search_stances else [])]
    paths: list[Path] = []
    square: list[SearchResult] = []
    with RolloutPool(args.processes, 64, backend=backend) as pool:
        reach = policy_reach(args, pool.info)
        placements = reach.grid(volume.grid)
        for start in starts:
            out = args.run_dir() / ("volume_search" if start == "square" else f"volume_search_{start}")
            lead_in = None if start == "square" else holding(start_actions(pool.info, start, args.load))
            search_args = SearchArgs(reward=args.reward, style=args.style, style_weight=args.style_weight, frames=reward.frames,
                                     seed=args.seed, out=out, iterations=volume.search_iterations, rollouts=volume.search_rollouts,
                                     sigma_init=volume.search_sigma_init, processes=args.processes, characters_per_process=64,
                                     smoothing_window=args.smoothing_window)
            bests = placement_search(search_args, reward, pool, progress, run_dir=out, placements=placements,
                                     init_mu=centre.best_actions, lead_in=lead_in)
            square = square or bests
            start_paths = [out / "datasets" / f"placement_{index:03d}.npz" for index in range(len(bests))]
            if not (resume and all(path.exists() for path in start_paths)):
                start_paths[0].parent.mkdir(parents=True, exist_ok=True)
                for path, dataset in zip(start_paths, record_datasets(bests, reward, search_args, placements, reach, backend=backend,
                                                                      lead_in=lead_in), strict=True):
                    np.savez_compressed(path, **dataset)  # type: ignore[arg-type]  # numpy's stub types **kwargs as its bool option
            paths += start_paths
    return paths, reach, [b.best_return for b in square], np.stack([b.best_actions for b in square])


def start_actions(info: ServerInfo, guard: str, load: str | None) -> list[float]:
    """The action that holds `guard` (a stance's), with the punching arm in `load` when given (`--load`)."""
    return info.stance_guard_actions[guard] if load is None else info.loaded_guard_actions[guard][load]


def arm_range(values: list[float]) -> tuple[float, float]:
    """--arm-range as (low, high); ValueError unless it is two scales, low first."""
    if len(values) != 2 or values[0] > values[1]:
        raise ValueError(f"--arm-range is two arm scales, the lower first (e.g. 0.75 1.0), not {values}")
    return values[0], values[1]


def run_train(args: TrainArgs, progress: bool = True, resume: bool = False, *, backend: Backend = LOCAL) -> Path:
    """The whole `punch train` command, with every training server on `backend`. Every stage checkpoints in
    its own folder of the run directory (search/, volume_search/, pretrain/, a2c/); `resume` continues the run
    in `args.out` from them."""
    started = time.perf_counter()
    if args.reach not in REACH_DEFAULTS:
        raise ValueError(f"--reach is 'volume' or 'spot', not '{args.reach}'")
    over_volume = args.reach == "volume"
    if args.guard != "square" and (not over_volume or args.search_stances or args.stance_share > 0):
        raise ValueError(f"--guard {args.guard} trains from that guard alone, over the reach volume: it goes without "
                         "--reach spot, --search-stances and --stance-share")
    if args.load is not None and args.guard == "square":
        raise ValueError(f"--load {args.load} draws the arm from a stance's guard: give --guard orthodox or southpaw too")
    if args.reach_distance is not None and (not over_volume or len(args.reach_distance) != 2
                                            or args.reach_distance[0] > args.reach_distance[1]):
        raise ValueError(f"--reach-distance is two distances over the volume, the nearer first (e.g. 0.70 0.85), not {args.reach_distance}")
    if args.reach_height is not None and (not over_volume or len(args.reach_height) != 2
                                          or args.reach_height[0] > args.reach_height[1]):
        raise ValueError(f"--reach-height is two heights over the volume, the lower first (e.g. 1.00 1.55), not {args.reach_height}")
    if args.init_from is not None:
        check_source(args.init_from)
    defaults = REACH_DEFAULTS[args.reach]
    reward = load_reward(args.reward, args.frames, style_named(args.style, args.style_weight))
    out = args.run_dir()
    if not resume and (out / CONFIG_FILE).exists():
        raise CheckpointError(f"{out} already holds a training run; continue it with `punch train --resume {out}` or choose another --out")
    write_config(out, args)
    timings = {}

    search_args = SearchArgs(reward=args.reward, style=args.style, style_weight=args.style_weight, frames=reward.frames,
                             seed=args.seed, out=out / "search",
                             iterations=args.search_iterations, rollouts=args.search_rollouts,
                             processes=args.processes, characters_per_process=min(64, args.search_rollouts),
                             smoothing_window=args.smoothing_window)
    _, search, _ = run_search(search_args, progress, resume=resume, backend=backend)
    dataset_paths = [out / "search" / "dataset.npz"]
    volume = VolumeArgs(grid=parse_grid(args.grid), search_iterations=args.volume_search_iterations,
                        search_rollouts=args.volume_search_rollouts, default_share=args.default_share,
                        stance_share=1.0 if args.guard != "square" else args.stance_share, lead_in_every=args.lead_in_every,
                        motions=MotionRange() if args.motions == "move" else None,
                        arms=ArmRange(arm_scale=arm_range(args.arm_range)) if args.arms == "sized" else None)
    reach, punches, grid_bests = None, search.best_actions[None], [search.best_return]
    if over_volume:
        dataset_paths, reach, grid_bests, punches = search_volume(args, volume, reward, search, progress, resume, backend)
    timings["search_s"] = time.perf_counter() - started

    data = load_datasets(dataset_paths)
    model = ActorCritic(data["observations"].shape[1], data["actions"].shape[1], seed=args.seed)
    processes = defaults.a2c_processes
    env = PunchVectorEnv(processes, args.a2c_characters, frames=reward.frames, smoothing_window=args.smoothing_window, backend=backend)
    # Every call of the simulator below is under the restart rule (A2C keeps its own); the env replaces servers
    # left idle by a long pretraining before their idle timeout ends them (PunchVectorEnv.reset).
    restarts = SimulatorRestarts(env.restart)
    try:
        guards = (args.guard,) if args.guard != "square" else ("orthodox", "southpaw")
        stance_guards = np.array([start_actions(env.info, name, args.load) for name in guards], dtype=np.float32)
        if args.lead_in_policies and reach is not None:
            punches = np.concatenate([punches, other_moves_punches(args.lead_in_policies, reach, punches.shape[1],
                                                                   env.info.mirror.actions, args.seed)])
        default_distance_m = env.info.default_bag.distance_m + lead_forward_m(args, env.info)
        if reach is not None:  # the default placement inside the policy's own reach
            default_distance_m = float(np.clip(default_distance_m, *reach.distance_m))
        default_bag = dataclasses.replace(env.info.default_bag, distance_m=default_distance_m)
        conditions = (ConditionSampler(reach, punches, volume, seed=args.seed + 1, default_bag=default_bag,
                                       stance_guards=stance_guards)
                      if reach is not None else None)
        validation: list[EpisodeConditions] | EpisodeStart | None = None
        if conditions is not None and reach is not None:
            placements = reach.sample(np.random.default_rng(args.seed + 2), env.num_envs)
            if volume.motions is not None:
                placements = volume.motions.draw(np.random.default_rng(args.seed + 2), placements)
            if volume.arms is not None:
                placements = volume.arms.draw(np.random.default_rng(args.seed + 3), placements)
            validation = placements
            if volume.stance_share > 0:
                validation = EpisodeStart(placements, conditions.stance_lead_ins(np.random.default_rng(args.seed + 4), env.num_envs))
        pretrained = load_checkpoint(out / "pretrain", "pretrain") if resume else None
        if pretrained is None:
            statistics = (restarts.run(functools.partial(distribution_observations, env, conditions, punches))
                          if conditions is not None else None)
            if args.init_from is not None:
                added = warm_start(model, args.init_from, env.info.observation_names,
                                   data["observations"] if statistics is None else statistics, env.info.spec_hash)
                pretrain_history = [{"warm_start": str(args.init_from), "new_inputs": added}]
                if args.init_from.suffix == ".onnx":  # a policy file holds no critic
                    pretrain_history += fit_critic(model, data, progress=progress)
            else:
                pretrain_args = PretrainArgs(epochs=args.pretrain_epochs, seed=args.seed,
                                             initial_sigma=defaults.pretrain_initial_sigma)
                pretrain_history = pretrain(model, data, pretrain_args, progress, statistics)
            save_checkpoint(out / "pretrain", "pretrain", {"model": model.state_dict(), "history": pretrain_history})
        else:
            model.load_state_dict(pretrained["model"])
            pretrain_history = pretrained["history"]
        timings["pretrain_s"] = time.perf_counter() - started - timings["search_s"]

        pretrained_return = restarts.run(functools.partial(evaluate_noise_free, model, env, reward))
        updates = args.a2c_updates or defaults.a2c_updates
        budget = args.a2c_time_budget_s if args.a2c_time_budget_s is not None else defaults.a2c_time_budget_s
        sigma_floor = args.a2c_sigma_floor if args.a2c_sigma_floor is not None else defaults.a2c_sigma_floor
        a2c_args = A2CArgs(updates=updates, characters=env.num_envs, advantage=args.advantage,
                           smoothing_window=args.smoothing_window, sigma_floor=sigma_floor,
                           time_budget_s=budget or None, seed=args.seed, snapshot_every=args.a2c_snapshot_every)

        run_facts = {"search_best_return": search.best_return, "reach": args.reach}  # in every policy file's summary

        def snapshot(update: int, current: ActorCritic) -> None:
            folder = out / "a2c" / "snapshots" / f"update_{update:05d}"
            export_policy(current, folder / "policy.onnx", contract=data["policy_metadata"], reward=reward.name,
                          style=reward.style, summary={**run_facts, "a2c_snapshot_update": update})
            save_checkpoint(folder, SNAPSHOT_KIND, {"update": update, "model": current.state_dict()})  # for --init-from

        model, a2c_history = train_a2c(model, reward, a2c_args, env, progress, run_dir=out / "a2c",
                                       start_rollouts=search.history[-1]["rollouts"] if search.history else 0,
                                       conditions=conditions, validation=validation, on_snapshot=snapshot)
        timings["a2c_s"] = time.perf_counter() - started - timings["search_s"] - timings["pretrain_s"]

        summary = {**run_facts, "pretrained_return": pretrained_return,
                   "a2c_best_eval_return": max(h["eval_return"] for h in a2c_history), "a2c_updates": len(a2c_history) - 1,
                   "grid_best_returns": [round(r, 4) for r in grid_bests]}
        validated = restarts.run(functools.partial(validate, model, env, reward, validation)) if validation is not None else None
        if validated is not None:
            summary["validation"] = validated.to_json()
        # The game draws the arm into the policy's load before it starts (punch_core's `start_load_from_metadata`).
        contract = {**data["policy_metadata"], **({START_LOAD: args.load} if args.load is not None else {})}
        policy_path = export_policy(model, out / "policy.onnx", contract=contract, reward=reward.name,
                                    style=reward.style, summary=summary)
        # A policy of one guard punches from there, at its volume's default placement.
        guard_start = None if args.guard == "square" else EpisodeStart(
            [default_bag] * env.num_envs, np.repeat(holding(start_actions(env.info, args.guard, args.load))[None], env.num_envs, 0))
        exported_return, features = restarts.run(functools.partial(run_exported_policy, policy_path, env, reward,
                                                                   start=guard_start))
    finally:
        env.close()
    timings["total_s"] = time.perf_counter() - started

    a2c_plots = write_a2c_report(out, a2c_history)
    ratio = exported_return / search.best_return if search.best_return > 0 else float("nan")
    motion = motion_report({"features": features, "feature_names": np.array(env.feature_names), "physics_hz": np.array(env.info.physics_hz)})
    impact = (f"first contact at {motion['impact_time_s']:.3f} s at {motion['impact_speed_mps']:.2f} m/s, contact point "
              f"{motion['contact_point_from_bag_centre_m']} m from the bag's centre" if motion["impact_time_s"] is not None
              else "no contact with the bag")
    lines = [
        f"# punch train: {reward.name}", "", f"- motion style: {style_label(reward.style)} (docs/style.md)",
        f"- trajectory search: best return {search.best_return:.4f} ({search_args.iterations} iterations of {search_args.rollouts} rollouts)",
        (f"- after pretraining ({args.pretrain_epochs} epochs, final actor MSE {pretrain_history[-1]['actor_mse']:.2e}): "
         f"noise-free return {pretrained_return:.4f}" if args.init_from is None else
         f"- warm start from {args.init_from} (its best policy, the snapshot, or the file's actor with a critic "
         f"fitted here; new inputs, at zero weight: "
         f"{', '.join(pretrain_history[0]['new_inputs']) or 'none'}): noise-free return {pretrained_return:.4f}"),
        f"- after A2C ({len(a2c_history) - 1} updates x {processes * args.a2c_characters} episodes, advantage '{args.advantage}', "
        f"sigma at least {a2c_args.sigma_floor}): "
        f"best noise-free return {max(h['eval_return'] for h in a2c_history):.4f}",
        f"- exported policy (onnxruntime, sigma 0) in the simulator: return {exported_return:.4f} = {100 * ratio:.1f}% of the search's best"
        if args.guard == "square" else
        f"- exported policy (onnxruntime, sigma 0) in the simulator, from the {args.guard} guard"
        f"{f' ({args.load} load)' if args.load else ''} at the default placement "
        f"{default_bag.distance_m:.2f} m ahead: return {exported_return:.4f} (the search above started from the square guard)",
        f"- reach: {args.reach}" + (f" ({len(grid_bests)} search placements; on {env.num_envs} validation placements, "
                                    f"sigma 0: success {100 * validated.success_rate:.1f}%, mean return {validated.mean_return:.4f})"
                                    if validated is not None else " (the default placement only)"),
        f"- the exported policy's punch: peak right-fist speed {motion['peak_fist_speed_mps']:.2f} m/s; {impact}",
        f"- timings: search {timings['search_s']:.1f} s, pretraining {timings['pretrain_s']:.1f} s, A2C {timings['a2c_s']:.1f} s, "
        f"total {timings['total_s']:.1f} s",
        f"- policy: `policy.onnx` (input `obs` [B, {env.info.observation_size}], outputs `mean`, `sigma` [B, {env.info.action_size}]; "
        f"metadata: spec hash {data['policy_metadata'][SPEC_HASH]})",
        "", "Search details: [search/report.md](search/report.md)",
    ]
    naturalness = punch_naturalness(features, env.feature_names, float(env.info.physics_hz))
    lines += ["", "## Naturalness of the exported policy's punch (docs/naturalness.md)", "",
              "The exported policy at sigma 0 in the simulator (the punch above); `punch eval` gives the same table over "
              "held-out placements and under noise. The captured punches: from movement onset to full reach.", "",
              *naturalness_table([("exported policy, sigma 0", summarise([naturalness]))], capture_figures())]
    if a2c_plots:
        lines += ["", "## A2C per update (a2c_metrics.csv)", ""] + [f"![{p.stem}]({p.name})" for p in a2c_plots]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "summary.json").write_text(json.dumps({"search_best_return": search.best_return, "pretrained_return": pretrained_return,
                                                  "exported_return": exported_return, "ratio": ratio, "motion": motion,
                                                  "naturalness": naturalness.to_json(), **timings}, indent=2) + "\n")
    return out

