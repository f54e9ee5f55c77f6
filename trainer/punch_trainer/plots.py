"""Plots written into run directories (PNG, matplotlib without a display)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_search(out: Path, result, dataset: dict) -> list[Path]:
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


def _save(figure, path: Path) -> Path:
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
