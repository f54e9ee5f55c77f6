"""`punch bench ...`: measured speed, written to BENCHMARKS.md with the command and the machine."""

from __future__ import annotations

import datetime
import json
import os
import platform
import re
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from punch_trainer.errors import GodotRunError, PunchError
from punch_trainer.options import bounds
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.cluster import RayBackend
from punch_trainer.sim.godot import ADDON_POLICIES, GODOT_PROJECT, PROJECT_ROOT, run_godot
from punch_trainer.sim.protocol import Message, reset_message, rollout_message, step_message
from punch_trainer.sim.server import ServerConnection, exchange

BENCHMARKS_FILE = PROJECT_ROOT / "BENCHMARKS.md"
DEMO_POLICY = ADDON_POLICIES / "straight.onnx"


@dataclass
class BenchEnvArgs:
    """The options of `punch bench env`."""

    characters: list[int] = field(default_factory=lambda: [1, 16, 64])
    """characters per process (N)"""
    processes: list[int] = field(default_factory=lambda: [1, 2])
    """Godot processes (K)"""
    frames: int = 50
    """physics frames per episode"""
    episodes: int = 6
    """episodes measured per configuration"""


@dataclass
class BenchInferenceArgs:
    """The options of `punch bench inference`."""

    policy: Path = DEMO_POLICY
    """policy to run"""
    characters: list[int] = field(default_factory=lambda: [1, 4, 16, 64, 100, 128, 256])
    """controllers measured at once, one measurement per count"""
    batches: int = 3
    """punches per controller"""
    skeleton_characters: list[int] = field(default_factory=lambda: [1, 16, 64], metadata=bounds(1, 256, max_items=8))
    """counts (of those in --characters) at which the skeleton writing is measured too: that many rigged characters
    (PunchSkeletonModifier on a converted CC0 character) punching at once"""


@dataclass
class BenchSearchArgs:
    """The options of `punch bench search`."""

    presets: list[str] = field(default_factory=lambda: ["straight", "straight100", "hook", "swing"])
    """reward presets to search"""
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    """one run of every method per preset and seed"""
    iterations: int = 100
    """iterations of every method"""
    rollouts: int = 64
    """population per iteration, the same for every method"""


@dataclass(frozen=True)
class EnvThroughput:
    processes: int
    characters_per_process: int
    mode: str  # "open loop" (rollout) or "closed loop" (reset + step per decision)
    character_frames_per_s: float
    # Open loop only: the two parts of an episode's cost.
    reset_ms: float | None = None
    steady_character_frames_per_s: float | None = None


@dataclass(frozen=True)
class RayOverhead:
    """Ray workers against local processes at one count K (`bench_ray`); times in ms."""

    workers: int
    characters: int
    """characters per worker"""
    local_batch_ms: float
    """one open-loop batch on K local Godot processes (the median of the rounds)"""
    ray_batch_ms: float
    """the same batch on K Ray workers"""
    overhead_ms: float
    overhead_pct: float
    driver_ms_per_worker: float
    """the trainer's own handling of one worker's request and reply"""
    local_character_frames_per_s: float


@dataclass(frozen=True)
class InferenceCost:
    """PunchController's cost at one count of controllers (`bench_inference`)."""

    controllers: int
    calls: int
    """ONNX Runtime calls"""
    rows: int
    """character-decisions in those calls"""
    usec_per_call: float
    usec_per_character_decision: float
    controller_usec_per_frame: float
    """the whole per-frame pass over all controllers while they punch (mean over batches)"""
    controller_usec_per_character_frame: float
    idle_controller_usec_per_frame: float
    """the same pass while they stand idle after their punches (median frame)"""
    skeleton: SkeletonCost | None = None
    """the skeleton writing at this count, where measured"""


@dataclass(frozen=True)
class SkeletonCost:
    """PunchSkeletonModifier's cost: `characters` rigged characters punching at once (`bench_skeleton`)."""

    rig: str
    bones: int
    written: int
    """bones the modifier writes each frame (spine, arms, hands and the fingers it curls into fists)"""
    characters: int
    character_frames: int
    """character-frames in which the modifiers wrote poses"""
    skeleton_usec_per_character_frame: float
    controller_usec_per_character_frame: float
    """the controllers' work in the same run, per character and physics frame"""


@dataclass(frozen=True)
class SearchBenchRun:
    """One search method's run on one preset and seed (`bench_search`)."""

    preset: str
    method: str
    seed: int
    final_return: float
    rollouts: int
    wall_s: float
    s_to_95: float
    """seconds until the best return reached 95% of the run's final"""
    rollouts_to_95: int


def machine_description() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def bench_env(args: BenchEnvArgs, seed: int = 0, *, backend: Backend = LOCAL) -> list[EnvThroughput]:
    """Character-physics-frames per second through the real socket, open and closed loop, on servers started
    on `backend`. Each measurement runs `episodes` full episodes (reset included) after one warm-up episode."""
    characters, processes, frames, episodes = args.characters, args.processes, args.frames, args.episodes
    rng = np.random.default_rng(seed)
    results = []
    configurations = [(k, n) for k in processes for n in characters]
    for k, n in tqdm(configurations, desc="bench env", unit="config"):
        servers = backend.start_servers(k, n)
        try:
            decisions = frames // servers[0].info.decision_period
            actions = rng.uniform(-1, 1, size=(n, decisions, servers[0].info.action_size)).astype(np.float32)
            rollout = rollout_message(actions)
            exchange(servers, [rollout] * k)  # warm-up
            start = time.perf_counter()
            for _ in range(episodes):
                exchange(servers, [rollout] * k)
            elapsed = time.perf_counter() - start
            # Split an episode's cost: resets alone, and the per-frame rate from a much longer rollout.
            start = time.perf_counter()
            for _ in range(episodes):
                exchange(servers, [reset_message(frames)] * k)
            reset_s = (time.perf_counter() - start) / episodes
            long = rollout_message(np.tile(actions, (1, 8, 1)))
            start = time.perf_counter()
            exchange(servers, [long] * k)
            long_s = time.perf_counter() - start
            steady = k * n * (8 * frames - frames) / max(long_s - elapsed / episodes, 1e-9)
            results.append(EnvThroughput(k, n, "open loop", k * n * frames * episodes / elapsed, 1000 * reset_s, steady))

            start = time.perf_counter()
            for _ in range(episodes):
                exchange(servers, [reset_message(frames)] * k)
                for decision in range(decisions):
                    step = step_message(actions[:, decision])
                    exchange(servers, [step] * k)
            elapsed = time.perf_counter() - start
            results.append(EnvThroughput(k, n, "closed loop", k * n * frames * episodes / elapsed))
        finally:
            for server in servers:
                server.close()
    return results


def _batch_seconds(servers: list[ServerConnection], rollout: Message, batches: int) -> float:
    """Mean wall time of one open-loop batch (every server one rollout message), after one warm-up batch."""
    exchange(servers, [rollout] * len(servers))
    start = time.perf_counter()
    for _ in range(batches):
        exchange(servers, [rollout] * len(servers))
    return (time.perf_counter() - start) / batches


def bench_ray(backend: Backend, processes: Sequence[int] = (1, 2, 3), characters: int = 64, frames: int = 50, batches: int = 6,
              rounds: int = 8, seed: int = 0) -> list[RayOverhead]:
    """Ray's cost against local processes at the same count K: open-loop batches of `characters` per worker,
    timed on local Godot processes and on Ray workers of `backend` (a cluster joined with `cluster.ray_cluster`),
    alternating `rounds` times so that both see the same machine. One row per K (times in ms)."""
    if not isinstance(backend, RayBackend):
        raise PunchError("bench_ray needs a Ray cluster: punch bench env --ray [ADDRESS|simulated]")
    rng = np.random.default_rng(seed)
    rows = []
    for k in tqdm(processes, desc="bench ray", unit="config"):
        local: list[ServerConnection] = []
        on_ray: list[ServerConnection] = []
        try:
            local = LOCAL.start_servers(k, characters)
            on_ray = backend.start_servers(k, characters)
            decisions = frames // local[0].info.decision_period
            rollout = rollout_message(rng.uniform(-1, 1, size=(characters, decisions, local[0].info.action_size)).astype(np.float32))
            times: dict[str, list[float]] = {"local": [], "ray": []}
            for _ in range(rounds):
                times["local"].append(_batch_seconds(local, rollout, batches))
                times["ray"].append(_batch_seconds(on_ray, rollout, batches))
            # The trainer's own serial work per worker: submitting a request and taking in a reply that is
            # already there (waited for, so only the handling is timed).
            driver_s = 0.0
            for _ in range(batches):
                start = time.perf_counter()
                for server in on_ray:
                    server.send(rollout)
                driver_s += time.perf_counter() - start
                time.sleep(2 * float(np.median(times["local"])) + 0.05)
                start = time.perf_counter()
                for server in on_ray:
                    server.receive()
                driver_s += time.perf_counter() - start
        finally:
            for server in local + on_ray:
                server.close()
        # Medians of the rounds: a round that the machine slowed for a moment does not move them.
        local_ms, ray_ms = 1000 * float(np.median(times["local"])), 1000 * float(np.median(times["ray"]))
        rows.append(RayOverhead(workers=k, characters=characters, local_batch_ms=local_ms, ray_batch_ms=ray_ms,
                                overhead_ms=ray_ms - local_ms, overhead_pct=100 * (ray_ms - local_ms) / local_ms,
                                driver_ms_per_worker=1000 * driver_s / (batches * k),
                                local_character_frames_per_s=k * characters * frames / (local_ms / 1000)))
    return rows


def ray_tables(rows: list[RayOverhead], frames: int = 50, projected_workers: Sequence[int] = (8, 64, 512)) -> str:
    """The measured rows, then throughput projected to more workers with the model written above the table."""
    lines = ["| workers K | characters per worker | local batch (ms) | Ray batch (ms) | Ray overhead (ms per batch) | overhead | "
             "trainer's handling per worker (ms) | local character-frames/s |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.workers:.0f} | {r.characters:.0f} | {r.local_batch_ms:.1f} | {r.ray_batch_ms:.1f} | "
                     f"{r.overhead_ms:.1f} | {r.overhead_pct:+.1f}% | {r.driver_ms_per_worker:.2f} | "
                     f"{r.local_character_frames_per_s:,.0f} |")
    # Model: a batch on W workers, each alone on its node's cores, takes one worker's batch time, plus Ray's
    # fixed round trip, plus the trainer's serial handling of W requests and replies: t(W) = t1 + a + b W.
    one = next(r for r in rows if r.workers == 1)
    b = float(np.median([r.driver_ms_per_worker for r in rows]))
    a = max(0.0, one.overhead_ms - b)
    characters = one.characters
    lines += ["", f"Projection: t(W) = t1 + a + b·W, with t1 = {one.local_batch_ms:.1f} ms (one local worker's batch of "
              f"{characters:.0f} characters x {frames} frames), a = {a:.1f} ms (the measured overhead at K = 1 less b, at least 0) "
              f"and b = {b:.2f} ms (the trainer's own handling of one worker's request and reply, timed with the reply already "
              "there: the part that grows with W, as the trainer sends and reads one message per worker); throughput = "
              "W x characters x frames / t(W). It assumes one worker per node's cores, a network as fast as loopback, and "
              "leaves out the trainer's per-batch work outside the exchange (the search's update).", "",
              "| workers W | projected batch (ms) | projected character-frames/s | of W x one worker's rate |", "|---|---|---|---|"]
    for w in projected_workers:
        batch_ms = one.local_batch_ms + a + b * w
        rate = w * characters * frames / (batch_ms / 1000)
        lines.append(f"| {w} | {batch_ms:.1f} | {rate:,.0f} | {rate / (w * one.local_character_frames_per_s):.0%} |")
    return "\n".join(lines)


def env_table(results: list[EnvThroughput]) -> str:
    lines = ["| processes K | characters per process N | mode | character-frames/s | reset (ms) | per-frame rate without resets |",
             "|---|---|---|---|---|---|"]
    for r in results:
        reset = f"{r.reset_ms:.1f}" if r.reset_ms is not None else ""
        steady = f"{r.steady_character_frames_per_s:,.0f}" if r.steady_character_frames_per_s is not None else ""
        lines.append(f"| {r.processes} | {r.characters_per_process} | {r.mode} | {r.character_frames_per_s:,.0f} | {reset} | {steady} |")
    return "\n".join(lines)


def write_section(name: str, command: str, body: str, measured: datetime.datetime | None = None) -> Path:
    """Replaces (or appends) the section `name` of BENCHMARKS.md, stamped with when it was `measured` (default: now)."""
    stamp = (measured or datetime.datetime.now(datetime.UTC)).strftime("%Y-%m-%d %H:%M UTC")
    section = (f"<!-- {name}:start -->\n## {name}\n\nCommand: `{command}`  \nMachine: {machine_description()}  \n"
               f"Measured: {stamp}\n\n{body}\n<!-- {name}:end -->")
    text = BENCHMARKS_FILE.read_text() if BENCHMARKS_FILE.exists() else "# Benchmarks\n\nMeasured figures; each section names the command that produced it.\n"
    pattern = re.compile(rf"<!-- {re.escape(name)}:start -->.*?<!-- {re.escape(name)}:end -->", re.S)
    text = pattern.sub(lambda _: section, text) if pattern.search(text) else text.rstrip() + "\n\n" + section + "\n"
    BENCHMARKS_FILE.write_text(text)
    return BENCHMARKS_FILE


def bench_search(args: BenchSearchArgs, plot_path: Path, characters_per_process: int = 64) -> list[SearchBenchRun]:
    """TTR, CEM and CMA-ES on the same presets, seeds and rollout budget. Returns one row per (preset,
    method, seed) and writes a plot of return against rollouts and against wall time to `plot_path`."""
    presets, seeds, iterations, rollouts = args.presets, args.seeds, args.iterations, args.rollouts
    from punch_trainer.learn.baselines import cem, cma_es
    from punch_trainer.learn.search import SearchArgs, trajectory_search
    from punch_trainer.reward.rewards import load_reward
    from punch_trainer.sim.rollouts import RolloutPool

    methods = {"TTR": lambda a, r, p: trajectory_search(a, r, p, progress=False).history, "CEM": cem, "CMA-ES": cma_es}
    rows, curves = [], {}
    with RolloutPool(1, characters_per_process) as pool:
        jobs = [(preset, method, seed) for preset in presets for method in methods for seed in seeds]
        for preset, method, seed in tqdm(jobs, desc="bench search", unit="run"):
            reward = load_reward(preset)
            search_args = SearchArgs(reward=preset, seed=seed, iterations=iterations, rollouts=rollouts, plateau_iterations=0)
            history = methods[method](search_args, reward, pool)
            final = history[-1]["best_return"]
            reach = next((h for h in history if h["best_return"] >= 0.95 * final), history[-1])
            rows.append(SearchBenchRun(preset=preset, method=method, seed=seed, final_return=final,
                                       rollouts=history[-1]["rollouts"], wall_s=history[-1]["elapsed_s"],
                                       s_to_95=reach["elapsed_s"], rollouts_to_95=reach["rollouts"]))
            curves[(preset, method, seed)] = history
    _plot_search_bench(curves, presets, list(methods), plot_path)
    return rows


def _plot_search_bench(curves: dict[tuple[str, str, int], list[dict[str, Any]]], presets: Sequence[str], methods: Sequence[str],
                       path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(2, len(presets), figsize=(4 * len(presets), 6.5), squeeze=False)
    for column, preset in enumerate(presets):
        for method, color in zip(methods, ["tab:red", "tab:blue", "tab:green"]):
            for (p, m, seed), history in curves.items():
                if p != preset or m != method:
                    continue
                label = method if seed == 0 else None
                axes[0][column].plot([h["rollouts"] for h in history], [h["best_return"] for h in history], color=color, alpha=0.7, label=label)
                axes[1][column].plot([h["elapsed_s"] for h in history], [h["best_return"] for h in history], color=color, alpha=0.7, label=label)
        axes[0][column].set_title(preset)
        axes[0][column].set_xlabel("rollouts")
        axes[1][column].set_xlabel("wall time (s)")
        for row in axes:
            row[column].set_ylabel("best return")
            row[column].grid(alpha=0.3)
    axes[0][0].legend()
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


def search_table(rows: list[SearchBenchRun]) -> str:
    lines = ["| preset | method | final best return (mean +- sd over seeds) | rollouts | wall time (s) | time to 95% of own final (s) |",
             "|---|---|---|---|---|---|"]
    keys = dict.fromkeys((r.preset, r.method) for r in rows)
    for preset, method in keys:
        group = [r for r in rows if r.preset == preset and r.method == method]
        finals = np.array([r.final_return for r in group])
        lines.append(f"| {preset} | {method} | {finals.mean():.3f} +- {finals.std():.3f} | {group[0].rollouts} | "
                     f"{np.mean([r.wall_s for r in group]):.1f} | {np.mean([r.s_to_95 for r in group]):.1f} |")
    return "\n".join(lines)


# Frames each batch's characters stand idle after their punches, to measure what idle controllers cost.
IDLE_FRAMES = 120


# The converted CC0 character the skeleton writing is measured on (52 bones, 30 of them fingers), when it can be made.
SKELETON_BENCH_CHARACTER = "mixamo_190"


CHARACTER_MAKER = PROJECT_ROOT / "tests" / "fixtures" / "characters"
"""the tests' maker of the CC0 characters (a test fixture, as the bench's Godot script is a test script)"""
CHARACTERS_DIR = PROJECT_ROOT / ".cache" / "characters"


def skeleton_bench_rig() -> Path | None:
    """The converted CC0 character's glb (made by the tests' `CHARACTER_MAKER` if it is not yet), or None when it
    cannot be made (then the rig the test script builds at run time is measured)."""
    command = [sys.executable, str(CHARACTER_MAKER), "--out", str(CHARACTERS_DIR), "--only", SKELETON_BENCH_CHARACTER]
    try:
        made = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
        manifest = json.loads((CHARACTERS_DIR / "characters.json").read_text()) if made.returncode == 0 else {}
    except (OSError, ValueError, subprocess.TimeoutExpired):
        return None
    files = [CHARACTERS_DIR / c["file"] for c in manifest.get("characters", []) if c.get("name") == SKELETON_BENCH_CHARACTER]
    return files[0] if files and files[0].is_file() else None


def bench_skeleton(policy: Path, characters: int, glb: Path | None, punches: int = 3) -> SkeletonCost:
    """PunchSkeletonModifier's time per character-frame, from `characters` copies of a rigged character (`glb`, else
    the test script's run-time rig), each playing an idle animation and punching a sandbag `punches` times with
    `policy` (tests/godot/skeleton_modifier.gd --bench), fingers curled into fists."""
    script = PROJECT_ROOT / "tests" / "godot" / "skeleton_modifier.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--",
                     f"--policy={Path(policy).resolve()}", f"--bench={characters}", f"--bench-punches={punches}",
                     *([f"--glb={glb.resolve()}"] if glb else [])], check=False, timeout_s=600)
    line = next((line for line in run.log.splitlines() if line.startswith("SKELETON_BENCH ")), None)
    if run.returncode != 0 or run.fatal_lines() or line is None:
        raise GodotRunError(f"the skeleton benchmark failed (exit code {run.returncode}):\n{run.log[-3000:]}", run.log)
    report = json.loads(line[len("SKELETON_BENCH "):])
    return SkeletonCost(rig=report["rig"], bones=report["bones"], written=report["written"], characters=report["characters"],
                        character_frames=report["character_frames"],
                        skeleton_usec_per_character_frame=report["skeleton_usec_per_character_frame"],
                        controller_usec_per_character_frame=report["controller_usec_per_character_frame"])


@dataclass(frozen=True)
class BenchSoakArgs:
    """The options of `punch bench soak`."""

    pairs: int = field(default=20, metadata=bounds(1, 64))
    """pairs of characters trading punches"""
    seconds: float = field(default=600.0, metadata=bounds(10.0, 7200.0))
    """how long they fight, s of game time"""
    seed: int = 1
    """the random commands' and hits' seed"""


def bench_soak(args: BenchSoakArgs) -> dict[str, Any]:
    """A long bout (tests/godot/bout_chaos.gd): `pairs` pairs trading random punches and combinations at each other's
    heads and torsos, cancelling and recovering at random, struck by the game up to knock-downs, for `seconds`; its
    report, with the process's memory, the engine's objects and the frame's cost twenty times over the run (at most
    every 30 s)."""
    sample_s = min(30.0, args.seconds / 20.0)
    script = PROJECT_ROOT / "tests" / "godot" / "bout_chaos.gd"
    wall_s = 60.0 + 0.5 * args.pairs * args.seconds  # about 0.1 s of wall time per pair and second on 2 cores: margin
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--",
                     f"--pairs={args.pairs}", f"--seconds={args.seconds}", f"--seed={args.seed}", f"--sample-s={sample_s}"],
                    check=False, timeout_s=wall_s)
    line = next((line for line in run.log.splitlines() if line.startswith("BOUT_CHAOS ")), None)
    if run.returncode != 0 or run.fatal_lines() or line is None:
        raise GodotRunError(f"the soak failed (exit code {run.returncode}):\n{run.log[-3000:]}", run.log)
    return dict(json.loads(line[len("BOUT_CHAOS "):]))


def soak_body(args: BenchSoakArgs, report: dict[str, Any]) -> str:
    """The soak's note and tables: what was promised and what held, and the samples over the run."""
    fighters = report["fighters"]
    started, finished = sum(f["started"] for f in fighters), sum(f["finished"] for f in fighters)
    outcomes: dict[str, int] = {}
    for fighter in fighters:
        for outcome, count in fighter["outcomes"].items():
            outcomes[outcome] = outcomes.get(outcome, 0) + count
    samples = report["samples"]
    if not samples:
        raise PunchError("the soak took no samples: run it longer")
    first, last = samples[0], samples[-1]
    note = (f"{args.pairs} pairs of the addon's characters facing each other in one headless Godot, each controller "
            f"punching its opponent's head or torso with random moves and combinations at random times, random cancels "
            f"and recoveries (some inside the signal handlers), and the game striking random parts up to knock-downs "
            f"(`recover()` some time later), for {args.seconds:.0f} s of game time at 120 Hz (`tests/godot/bout_chaos.gd`, "
            f"seed {args.seed}), then 5 s of quiet. Every promise is checked as the signals come and every second on the "
            f"bodies (finite, near their character, above the floor). The frame's cost is the wall time between two physics "
            f"frames (headless, frames back to back: the whole frame), the controllers' part `PunchProbe.take_frame_cost_usec`.")
    promises = ["| checked | result |", "|---|---|",
                f"| punches started / finished | {started} / {finished} |",
                f"| outcomes (landed / blocked / whiffed) | {outcomes.get('landed', 0)} / {outcomes.get('blocked', 0)} / "
                f"{outcomes.get('whiffed', 0)} |",
                f"| hits taken, knock-downs, game hits | {sum(f['hits_taken'] for f in fighters)}, "
                f"{sum(f['knocked_down'] for f in fighters)}, {report['game_hits']} |",
                f"| broken promises (a start without one finish, a NaN or lost body, an unknown ending, ...) | "
                f"{report['problem_count']} |",
                f"| Godot's memory, first sample to last | {first['memory_mb']:.1f} MB to {last['memory_mb']:.1f} MB "
                f"(largest {max(s['memory_mb'] for s in samples):.1f}) |",
                f"| the process's resident memory, first sample to last | {first['rss_mb']:.1f} MB to "
                f"{last['rss_mb']:.1f} MB (largest {max(s['rss_mb'] for s in samples):.1f}) |",
                f"| engine objects, nodes, first sample to last | {first['objects']} to {last['objects']}, "
                f"{first['nodes']} to {last['nodes']} |"]
    rows = ["| game time (s) | Godot's memory (MB) | resident (MB) | objects | nodes | frame (µs, mean since the sample "
            "before) | controllers (µs) |", "|---|---|---|---|---|---|---|"]
    rows += [f"| {s['s']:.0f} | {s['memory_mb']:.1f} | {s['rss_mb']:.1f} | {s['objects']} | {s['nodes']} | "
             f"{s['frame_usec']:.0f} | {s['controllers_usec']:.0f} |" for s in samples]
    return "\n".join([note, "", *promises, "", *rows])


def bench_inference(args: BenchInferenceArgs, sigma: float = 0.3) -> list[InferenceCost]:
    """PunchController's cost in Godot, from `batches` punches of every controller at once for each count:
    ONNX Runtime time per call and per character-decision (all controllers share the policy, so one call per
    decision tick), and the controllers' whole work per physics frame (sensing, inference, driving); at the counts
    in `skeleton_characters`, also PunchSkeletonModifier's writing of rigged skeletons (`bench_skeleton`)."""
    policy, characters, batches = args.policy, args.characters, args.batches
    rig = skeleton_bench_rig() if set(characters) & set(args.skeleton_characters) else None
    import tempfile

    from punch_trainer.pipelines.evaluation import run_episodes

    rows = []
    for count in tqdm(characters, desc="bench inference", unit="config"):
        with tempfile.TemporaryDirectory() as frames_dir:
            episodes = [{"sigma": sigma, "seed": episode} for episode in range(count * batches)]
            meta = run_episodes(policy, episodes, Path(frames_dir), record=True, characters=count, idle_frames=IDLE_FRAMES)
        inference = meta["inference"]
        frame_usec = float(np.mean(meta["controller_frame_usec_per_batch"]))
        # Per frame: the median, as a rare frame in which the OS took the thread away outweighs a mean of ~1 µs.
        idle_usec = float(np.median(np.concatenate(meta["idle_controller_frame_usec_per_batch"])))
        skeleton = bench_skeleton(policy, count, rig, batches) if count in args.skeleton_characters else None
        rows.append(InferenceCost(controllers=count, calls=inference["calls"], rows=inference["rows"],
                                  usec_per_call=inference["usec"] / inference["calls"],
                                  usec_per_character_decision=inference["usec"] / inference["rows"],
                                  controller_usec_per_frame=frame_usec, controller_usec_per_character_frame=frame_usec / count,
                                  idle_controller_usec_per_frame=idle_usec, skeleton=skeleton))
    return rows


def inference_table(rows: list[InferenceCost]) -> str:
    """The controllers' table; then, where measured, the skeleton writing beside the controllers' work."""
    lines = ["| controllers | ONNX Runtime calls | µs per call | µs per character-decision | controller work per physics frame (µs) | per character (µs) | all idle: work per frame (µs) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.controllers} | {r.calls} | {r.usec_per_call:.1f} | {r.usec_per_character_decision:.2f} | "
                     f"{r.controller_usec_per_frame:.0f} | {r.controller_usec_per_character_frame:.2f} | "
                     f"{r.idle_controller_usec_per_frame:.2f} |")
    measured = [r.skeleton for r in rows if r.skeleton]
    if not measured:
        return "\n".join(lines)
    first = measured[0]
    rig = (f"the converted CC0 character `{first.rig}` ({first.bones} bones)" if first.rig == SKELETON_BENCH_CHARACTER
           else f"the test script's run-time rig `{first.rig}` ({first.bones} bones; the CC0 character could not be made)")
    lines += ["", f"Skeleton writing (PunchSkeletonModifier): its own pass per character-frame in which it wrote (reading the "
              f"simulated bodies and the animation's pose, posing, writing {first.written} bones: spine, clavicles, arms, hands and "
              f"the fingers curled into fists), on that many copies of {rig} with an idle animation, each punching its sandbag "
              "as often as the controllers above (tests/godot/skeleton_modifier.gd --bench); beside it, the controllers' work "
              "per character-frame in the same run. Skinning and the skeleton's own update are the engine's, as without the "
              "modifier. Target: under 10 µs per character-frame.", "",
              "| rigged characters | skeleton writing per character-frame (µs) | controller work per character-frame, same run (µs) | "
              "character-frames written |", "|---|---|---|---|"]
    for s in measured:
        lines.append(f"| {s.characters} | {s.skeleton_usec_per_character_frame:.2f} | {s.controller_usec_per_character_frame:.2f} | "
                     f"{s.character_frames} |")
    return "\n".join(lines)
