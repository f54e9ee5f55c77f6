"""`punch selfcheck`: the whole stack end to end. A tiny actor made with torch is exported to ONNX, run by
onnxruntime in Python and by the extension inside headless Godot, and the two must agree within 1e-5; the
Godot side also proves that Jolt is the active physics engine."""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import onnxruntime
import torch

from punch_trainer.errors import SelfCheckError
from punch_trainer.learn.export import export_onnx
from punch_trainer.sim.godot import GODOT_PROJECT, run_godot

TOLERANCE = 1e-5
REPORT_PREFIX = "PUNCH_SELFCHECK "


class TinyActor(torch.nn.Module):
    """A small actor with separate mean and sigma heads, the shape every exported policy has."""

    def __init__(self, obs_dim: int = 12, act_dim: int = 10, hidden: int = 32):
        super().__init__()
        self.body = torch.nn.Sequential(torch.nn.Linear(obs_dim, hidden), torch.nn.Tanh())
        self.mean = torch.nn.Linear(hidden, act_dim)
        self.log_sigma = torch.nn.Linear(hidden, act_dim)

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        features = self.body(obs)
        return torch.tanh(self.mean(features)), torch.exp(self.log_sigma(features))


@dataclass(frozen=True)
class SelfCheckArgs:
    """The options of `punch selfcheck`."""

    batch: int = 8
    """rows of the test input batch"""
    seed: int = 0
    """seed of the test model and input"""


@dataclass(frozen=True)
class SelfCheckReport:
    """What the self-check measured."""

    godot_version: str
    physics_engine: str
    extension_version: str
    onnxruntime_version: str
    onnxruntime_library: str
    batch: int
    max_abs_difference: float

    def lines(self) -> list[str]:
        return [
            f"Godot          {self.godot_version}",
            f"Physics        {self.physics_engine}",
            f"Extension      punch_controller {self.extension_version}",
            f"ONNX Runtime   {self.onnxruntime_version} ({self.onnxruntime_library})",
            f"Policy check   batch of {self.batch}: Godot/ort vs Python/onnxruntime max |diff| = "
            f"{self.max_abs_difference:.2e} (limit {TOLERANCE:g})",
        ]


def make_model(directory: Path, *, obs_dim: int = 12, act_dim: int = 10, seed: int = 0) -> Path:
    """Exports a seeded TinyActor to `directory`/tiny_actor.onnx."""
    torch.manual_seed(seed)
    return export_onnx(TinyActor(obs_dim, act_dim), obs_dim, directory / "tiny_actor.onnx",
                         metadata={"purpose": "punch selfcheck"}, seed=seed)


def run_selfcheck(args: SelfCheckArgs = SelfCheckArgs(), *, work_dir: Path | None = None) -> SelfCheckReport:
    """Runs the self-check and returns its report; raises SelfCheckError when any part fails."""
    batch, seed = args.batch, args.seed
    with tempfile.TemporaryDirectory(prefix="punch_selfcheck_") as scratch:
        directory = Path(work_dir or scratch)
        directory.mkdir(parents=True, exist_ok=True)
        model = make_model(directory, seed=seed)
        session = onnxruntime.InferenceSession(str(model), providers=["CPUExecutionProvider"])
        obs_dim = session.get_inputs()[0].shape[1]
        inputs = np.random.default_rng(seed).normal(size=(batch, obs_dim)).astype(np.float32)
        expected = dict(zip([o.name for o in session.get_outputs()], session.run(None, {"obs": inputs}), strict=True))
        request = directory / "input.json"
        request.write_text(json.dumps({"batch": batch, "values": inputs.ravel().tolist()}))

        run = run_godot(
            ["--headless", "--path", str(GODOT_PROJECT), "--script", "res://tools/selfcheck.gd",
             "--", f"--model={model.resolve()}", f"--input={request.resolve()}"],
            check=False,
        )
    report = _parse_report(run.log)
    problems = list(report.get("problems", []))
    if run.returncode != 0 and not problems:
        problems.append(f"Godot exited with code {run.returncode}")
    problems += [f"Godot log: {line}" for line in run.fatal_lines()]

    worst = float("inf")
    outputs = report.get("model", {}).get("outputs", {})
    for name, want in expected.items():
        got = np.asarray(outputs.get(name, []), dtype=np.float64)
        if got.size != want.size:
            problems.append(f"output '{name}': Godot returned {got.size} values, expected {want.size}")
            continue
        difference = float(np.max(np.abs(got - want.ravel())))
        worst = difference if worst == float("inf") else max(worst, difference)
        if not difference <= TOLERANCE:
            problems.append(f"output '{name}': Godot/ort and Python/onnxruntime differ by {difference:.3g}")
    if problems:
        raise SelfCheckError("self-check failed:\n  " + "\n  ".join(problems) + "\n--- Godot log ---\n" + run.log[-4000:])
    extension = report["extension"]
    return SelfCheckReport(
        godot_version=report["godot"],
        physics_engine=report["physics"]["engine"],
        extension_version=extension["extension"],
        onnxruntime_version=extension["onnxruntime"],
        onnxruntime_library=extension["onnxruntime_library"],
        batch=batch,
        max_abs_difference=worst,
    )


def _parse_report(log: str) -> dict[str, Any]:
    for line in log.splitlines():
        if line.startswith(REPORT_PREFIX):
            try:
                report: dict[str, Any] = json.loads(line[len(REPORT_PREFIX):])
                return report
            except json.JSONDecodeError as error:
                raise SelfCheckError(f"unreadable self-check report from Godot: {error}") from None
    raise SelfCheckError("Godot printed no self-check report:\n" + log[-4000:])
