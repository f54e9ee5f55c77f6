"""`punch bench ...`: measured speed, written to BENCHMARKS.md with the command and the machine."""

from __future__ import annotations

import datetime
import os
import platform
import re
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from punch_trainer.godot import PROJECT_ROOT
from punch_trainer.protocol import Message
from punch_trainer.server import TrainingServer

BENCHMARKS_FILE = PROJECT_ROOT / "BENCHMARKS.md"


@dataclass(frozen=True)
class EnvThroughput:
    processes: int
    characters_per_process: int
    mode: str  # "open loop" (rollout) or "closed loop" (reset + step per decision)
    character_frames_per_s: float
    # Open loop only: the two parts of an episode's cost.
    reset_ms: float | None = None
    steady_character_frames_per_s: float | None = None


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


def _gather(servers: list[TrainingServer], messages: list[Message]) -> list[Message]:
    for server, message in zip(servers, messages, strict=True):
        server.send(message)
    return [server.receive() for server in servers]


def bench_env(characters=(1, 16, 64), processes=(1, 2), frames: int = 50, episodes: int = 6, seed: int = 0) -> list[EnvThroughput]:
    """Character-physics-frames per second through the real socket, open and closed loop. Each measurement
    runs `episodes` full episodes (reset included) after one warm-up episode."""
    rng = np.random.default_rng(seed)
    results = []
    configurations = [(k, n) for k in processes for n in characters]
    for k, n in tqdm(configurations, desc="bench env", unit="config"):
        servers = [TrainingServer(n) for _ in range(k)]
        try:
            decisions = frames // servers[0].info.decision_period
            actions = rng.uniform(-1, 1, size=(n, decisions, 10)).astype(np.float32)
            rollout = Message("rollout", arrays={"actions": actions})
            _gather(servers, [rollout] * k)  # warm-up
            start = time.perf_counter()
            for _ in range(episodes):
                _gather(servers, [rollout] * k)
            elapsed = time.perf_counter() - start
            # Split an episode's cost: resets alone, and the per-frame rate from a much longer rollout.
            start = time.perf_counter()
            for _ in range(episodes):
                _gather(servers, [Message("reset", {"frames": frames})] * k)
            reset_s = (time.perf_counter() - start) / episodes
            long = Message("rollout", arrays={"actions": np.tile(actions, (1, 8, 1))})
            start = time.perf_counter()
            _gather(servers, [long] * k)
            long_s = time.perf_counter() - start
            steady = k * n * (8 * frames - frames) / max(long_s - elapsed / episodes, 1e-9)
            results.append(EnvThroughput(k, n, "open loop", k * n * frames * episodes / elapsed, 1000 * reset_s, steady))

            start = time.perf_counter()
            for _ in range(episodes):
                _gather(servers, [Message("reset", {"frames": frames})] * k)
                for decision in range(decisions):
                    step = Message("step", arrays={"actions": actions[:, decision]})
                    _gather(servers, [step] * k)
            elapsed = time.perf_counter() - start
            results.append(EnvThroughput(k, n, "closed loop", k * n * frames * episodes / elapsed))
        finally:
            for server in servers:
                server.close()
    return results


def env_table(results: list[EnvThroughput]) -> str:
    lines = ["| processes K | characters per process N | mode | character-frames/s | reset (ms) | per-frame rate without resets |",
             "|---|---|---|---|---|---|"]
    for r in results:
        reset = f"{r.reset_ms:.1f}" if r.reset_ms is not None else ""
        steady = f"{r.steady_character_frames_per_s:,.0f}" if r.steady_character_frames_per_s is not None else ""
        lines.append(f"| {r.processes} | {r.characters_per_process} | {r.mode} | {r.character_frames_per_s:,.0f} | {reset} | {steady} |")
    return "\n".join(lines)


def write_section(name: str, command: str, body: str) -> Path:
    """Replaces (or appends) the section `name` of BENCHMARKS.md."""
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    section = (f"<!-- {name}:start -->\n## {name}\n\nCommand: `{command}`  \nMachine: {machine_description()}  \n"
               f"Measured: {stamp}\n\n{body}\n<!-- {name}:end -->")
    text = BENCHMARKS_FILE.read_text() if BENCHMARKS_FILE.exists() else "# Benchmarks\n\nMeasured figures; each section names the command that produced it.\n"
    pattern = re.compile(rf"<!-- {re.escape(name)}:start -->.*?<!-- {re.escape(name)}:end -->", re.S)
    text = pattern.sub(lambda _: section, text) if pattern.search(text) else text.rstrip() + "\n\n" + section + "\n"
    BENCHMARKS_FILE.write_text(text)
    return BENCHMARKS_FILE
