"""Plots written into run directories (PNG, matplotlib without a display)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from punch_trainer.learn.search import SearchResult

plt.switch_backend("Agg")  # files only, no display


def plot_search(out: Path, result: SearchResult, dataset: dict[str, np.ndarray]) -> list[Path]:
    """Return against iterations and rollouts, sigma over iterations, and the 3D path of the fists."""
    history = result.history
    paths = []
    if history:
        iterations = [h["iteration"] for h in history]
        figure, (by_iteration, by_rollouts) = plt.subplots(1, 2, figsize=(10, 3.8))
        for axis, x, label in [(by_iteration, iterations, "iteration"), (by_rollouts, [h["rollouts"] for h in history], "rollouts")]:
            axis.plot(x, [h["best_return"] for h in history], label="best")
            axis.plot(x, [h["mean_return"] for h in history], label="mean of the iteration's samples", alpha=0.6)
            axis.set_xlabel(label)
            axis.set_ylabel("return")
            axis.grid(alpha=0.3)
        by_iteration.legend()
        figure.suptitle("Trajectory search: return")
        figure.tight_layout()
        paths.append(_save(figure, out / "return.png"))

        figure, axis = plt.subplots(figsize=(5, 3.8))
        axis.plot(iterations, [h["sigma_mean"] for h in history])
        axis.set_xlabel("iteration")
        axis.set_ylabel("mean sigma")
        axis.set_yscale("log")
        axis.grid(alpha=0.3)
        axis.set_title("Trajectory search: sigma")
        figure.tight_layout()
        paths.append(_save(figure, out / "sigma.png"))

    names = [str(n) for n in dataset["feature_names"]]
    f = dataset["features"]
    col = names.index
    figure = plt.figure(figsize=(6, 5))
    axis = figure.add_subplot(projection="3d")
    for side, color in [("r", "tab:red"), ("l", "tab:blue")]:
        xyz = f[:, col(f"fist_{side}_pos_x"):col(f"fist_{side}_pos_z") + 1]
        # Plotted with z (toward the bag) across, x sideways, y up.
        axis.plot(xyz[:, 2], xyz[:, 0], xyz[:, 1], color=color, label=f"{'right' if side == 'r' else 'left'} fist")
        axis.scatter(xyz[0, 2], xyz[0, 0], xyz[0, 1], color=color, s=12)
    bag = f[0, col("bag_pos_x"):col("bag_pos_z") + 1]
    axis.scatter(bag[2], bag[0], bag[1], color="black", s=40, label="bag centre (start)")
    axis.set_xlabel("z toward bag (m)")
    axis.set_ylabel("x left (m)")
    axis.set_zlabel("y up (m)")
    axis.legend(loc="upper left", fontsize=8)
    axis.set_title("Fist paths of the best trajectory")
    paths.append(_save(figure, out / "fist_path.png"))
    return paths


def plot_replay(out: Path, sigmas: list[float], rows: list[dict[str, Any]], analyses: list[dict[str, Any]], best_return: float | None,
                paths_per_sigma: int = 40) -> list[Path]:
    """Fig. 10: return ratio and success rate against sigma. Fig. 11: right-fist paths (side and top views)
    and impact points at a low, a middle and the highest sigma."""
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    if best_return:
        left.plot(sigmas, [r["return_ratio"] for r in rows], marker="o")
        left.set_ylabel("mean return / search best")
    else:
        left.plot(sigmas, [r["mean_return"] for r in rows], marker="o")
        left.set_ylabel("mean return")
    right.plot(sigmas, [100 * r["success_rate"] for r in rows], marker="o", label="return > 0")
    right.plot(sigmas, [100 * r["hit_rate"] for r in rows], marker="s", alpha=0.7, label="right fist touches the bag")
    right.set_ylabel("% of punches")
    right.set_ylim(0, 105)
    right.legend(fontsize=8)
    for axis in (left, right):
        axis.set_xlabel("runtime noise sigma")
        axis.grid(alpha=0.3)
    figure.suptitle("Replay through PunchController: quality against noise")
    figure.tight_layout()
    paths = [_save(figure, out / "replay_returns.png")]

    shown = sorted({0, len(sigmas) // 2, len(sigmas) - 1})
    figure, axes = plt.subplots(2, len(shown), figsize=(4 * len(shown), 7), squeeze=False)
    for column, index in enumerate(shown):
        fist, impacts = analyses[index]["fist_paths"], analyses[index]["impacts"]
        for row, (axis_index, label) in enumerate([(1, "y up (m)"), (0, "x left (m)")]):
            axis = axes[row][column]
            for path in fist[:paths_per_sigma]:
                axis.plot(path[:, 2], path[:, axis_index], color="tab:red", alpha=0.25, linewidth=0.8)
            if len(impacts):
                axis.scatter(impacts[:, 2], impacts[:, axis_index], s=4, color="black", alpha=0.4, label="impact points")
            axis.set_xlabel("z toward the bag (m)")
            axis.set_ylabel(label)
            axis.set_aspect("equal", adjustable="datalim")
            axis.grid(alpha=0.3)
            axis.set_title(f"sigma {sigmas[index]:.2f}, {'side' if row == 0 else 'top'} view", fontsize=10)
    figure.suptitle(f"Right-fist paths ({paths_per_sigma} per sigma) and impact points")
    figure.tight_layout()
    paths.append(_save(figure, out / "replay_paths.png"))
    return paths


def plot_eval(out: Path, placements: list[dict[str, float]], evaluations: list[dict[str, Any]]) -> list[Path]:
    """`punch eval`: success of the first condition at sigma 0 over the reach volume (side x height, one panel per
    distance band, one row per policy) and success against sigma of each condition measured under noise."""
    points = np.array([[p["distance_m"], p["height_m"], p["side_m"]] for p in placements])
    edges = np.quantile(points[:, 0], [0, 1 / 3, 2 / 3, 1])
    figure, axes = plt.subplots(len(evaluations), 3, figsize=(11, 3.6 * len(evaluations)), squeeze=False)
    for row, evaluation in enumerate(evaluations):
        hits = np.array(evaluation["success_at_sigma0"], dtype=bool)
        for band in range(3):
            axis = axes[row][band]
            inside = (points[:, 0] >= edges[band]) & (points[:, 0] <= edges[band + 1])
            for mask, colour, label in [(inside & hits, "tab:green", "success"), (inside & ~hits, "tab:red", "miss")]:
                axis.scatter(points[mask, 2], points[mask, 1], color=colour, s=40, label=label)
            axis.set_xlim(points[:, 2].max() + 0.03, points[:, 2].min() - 0.03)  # the character's right on the right
            axis.set_xlabel("side (m, + = the character's left)")
            axis.set_ylabel("height (m)")
            axis.grid(alpha=0.3)
            axis.set_title(f"{_short(evaluation['policy'])}: {edges[band]:.2f}-{edges[band + 1]:.2f} m ahead", fontsize=9)
        axes[row][0].legend(fontsize=8)
    figure.suptitle("Success at sigma 0 on held-out placements, seen from behind the character")
    figure.tight_layout()
    paths = [_save(figure, out / "eval_volume.png")]

    # Success against sigma for each condition measured under noise (with the first condition's sigma-0 row
    # where it has none of its own), when there are few enough to read.
    first = evaluations[0]["rows"][0]["condition"]
    noisy = list(dict.fromkeys(r["condition"] for r in evaluations[0]["rows"] if r["sigma"] > 0))
    if not noisy or len(noisy) * len(evaluations) > 8:
        return paths
    figure, axis = plt.subplots(figsize=(6.5, 4))
    for evaluation in evaluations:
        for condition, style in zip(noisy, ["-", "--", ":", "-."] * 2, strict=False):
            rows = [r for r in evaluation["rows"] if r["condition"] == condition]
            if not any(r["sigma"] == 0 for r in rows):
                rows += [r for r in evaluation["rows"] if r["sigma"] == 0 and r["condition"] == first][:1]
            rows = sorted(rows, key=lambda r: r["sigma"])
            axis.plot([r["sigma"] for r in rows], [100 * r["success_rate"] for r in rows], style, marker="o",
                      label=f"{_short(evaluation['policy'])}, {condition}")
    axis.set_xlabel("runtime noise sigma")
    axis.set_ylabel("success (%)")
    axis.set_ylim(0, 102)
    axis.grid(alpha=0.3)
    axis.legend(fontsize=8)
    figure.suptitle("Success against noise on held-out placements")
    figure.tight_layout()
    paths.append(_save(figure, out / "eval_sigma.png"))
    return paths


def plot_a2c(out: Path, history: list[dict[str, Any]]) -> list[Path]:
    """A2C's diagnostics per update (`learn.a2c`'s history): returns, the two losses, entropy and sigma, and
    each reward term's part of the mean episode return."""
    updates = [row for row in history if row["update"] > 0 and "policy_loss" in row]
    if not updates:
        return []
    x = [row["update"] for row in updates]
    terms = sorted({key for row in updates for key in row if key.startswith("reward/")})
    figure, ((returns, losses), (spread, by_term)) = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    returns.plot(x, [row["mean_return"] for row in updates], label="mean return of the update's episodes")
    returns.plot(x, [row["eval_return"] for row in updates], label="noise-free return (evaluation)")
    returns.set_ylabel("return")
    losses.plot(x, [row["policy_loss"] for row in updates], label="policy loss")
    losses.plot(x, [row["value_loss"] for row in updates], label="value loss")
    losses.set_yscale("symlog", linthresh=1e-3)  # the value loss can be orders of magnitude above the policy loss
    losses.set_ylabel("loss")
    spread.plot(x, [row["entropy"] for row in updates], label="entropy (nats)")
    sigma_axis = spread.twinx()
    sigma_axis.plot(x, [row["sigma_mean"] for row in updates], color="tab:orange", label="mean sigma")
    sigma_axis.set_ylabel("mean sigma")
    spread.set_ylabel("entropy (nats)")
    spread.legend(handles=spread.get_lines() + sigma_axis.get_lines(), fontsize=8)
    for term in terms:
        by_term.plot(x, [row.get(term, np.nan) for row in updates], label=term.removeprefix("reward/"))
    by_term.set_ylabel("mean episode return of the term")
    for axis in (returns, losses, by_term):
        axis.legend(fontsize=8)
    for axis in (returns, losses, spread, by_term):
        axis.grid(alpha=0.3)
    for axis in (spread, by_term):
        axis.set_xlabel("update")
    figure.suptitle("A2C diagnostics per update")
    figure.tight_layout()
    return [_save(figure, out / "a2c_diagnostics.png")]


def _short(policy: str) -> str:
    """A policy's file and folder name: runs/demo_straight/policy.onnx -> demo_straight/policy.onnx."""
    path = Path(policy)
    return f"{path.parent.name}/{path.name}"


def _save(figure: Figure, path: Path) -> Path:
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
