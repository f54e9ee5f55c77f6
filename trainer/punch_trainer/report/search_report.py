"""The run directory of a trajectory search: config, metrics, dataset, plots and a Markdown report."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from punch_trainer import __version__
from punch_trainer.capture.bvh import DEFAULT_BVH, captured_punch
from punch_trainer.learn.checkpoint import write_config
from punch_trainer.learn.search import SearchArgs, SearchResult
from punch_trainer.report.mocap import plot_against_capture
from punch_trainer.report.plots import plot_search
from punch_trainer.reward.rewards import Reward
from punch_trainer.sim.server import ServerInfo


def write_search_run(out: Path, args: SearchArgs, reward: Reward, result: SearchResult, dataset: dict[str, np.ndarray],
                     report: dict[str, Any], info: ServerInfo) -> None:
    """Writes everything a search leaves in its run directory."""
    out.mkdir(parents=True, exist_ok=True)
    write_config(out, args, frames=reward.frames, punch_version=__version__, spec_hash=info.spec_hash,
                 extension_version=info.extension_version,
                 clip_epsilon=args.clip_epsilon if args.clip_epsilon is not None else reward.search_clip_epsilon)
    with open(out / "metrics.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(result.history[0]) if result.history else ["iteration"])
        writer.writeheader()
        writer.writerows(result.history)
    np.savez_compressed(out / "dataset.npz", **dataset)  # type: ignore[arg-type]  # numpy's stub types **kwargs as its bool option

    plots = plot_search(out, result, dataset)

    capture_plot = plot_against_capture(out, dataset)
    if capture_plot is not None:
        plots.append(capture_plot)
        report["captured_punch_peak_speed_mps"] = float(captured_punch(DEFAULT_BVH)["peak_speed_mps"])
    lines = [
        f"# Trajectory search: {reward.name}", "",
        f"- best return: {result.best_return:.4f} ({', '.join(f'{k} {v:.4f}' for k, v in result.best_terms.items())})",
        f"- iterations: {len(result.history)}, rollouts: {result.history[-1]['rollouts'] if result.history else 1}, "
        f"wall time: {result.history[-1]['elapsed_s'] if result.history else 0:.1f} s",
        f"- episode: {reward.frames} frames at {info.physics_hz} Hz = {reward.frames / info.physics_hz:.2f} s, "
        f"{reward.frames // args.decision_period} decisions, smoothing window {args.smoothing_window}",
        f"- peak right-fist speed: {report['peak_fist_speed_mps']:.2f} m/s at {report['peak_fist_speed_time_s']:.3f} s",
    ]
    if report["impact_time_s"] is not None:
        lines.append(f"- first contact with the bag: {report['impact_time_s']:.3f} s at {report['impact_speed_mps']:.2f} m/s; "
                     f"contact point relative to the bag's centre (x left, y up, z away): {report['contact_point_from_bag_centre_m']} m")
    else:
        lines.append(f"- no contact with the bag (closest distance {report['closest_fist_bag_distance_m']:.3f} m)")
    if "captured_punch_peak_speed_mps" in report:
        lines.append(f"- captured punch (CMU 143/23, scaled to this arm): peak hand speed {report['captured_punch_peak_speed_mps']:.2f} m/s; "
                     "fist_vs_capture.png compares the paths, aligned at the shoulder")
    lines += ["", "## Plots", ""] + [f"![{p.stem}]({p.name})" for p in plots]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "motion.json").write_text(json.dumps(report, indent=2) + "\n")

