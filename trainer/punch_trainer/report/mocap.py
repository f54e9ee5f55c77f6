"""The paper's Fig. 4: a searched fist path against the captured punch's hand path (`capture.bvh`), both relative
to the punching shoulder and scaled by arm length."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from punch_trainer.capture.bvh import CHARACTER_ARM_LENGTH_M, CHARACTER_RIGHT_SHOULDER, DEFAULT_BVH, captured_punch


def plot_against_capture(out: Path, dataset: dict[str, np.ndarray], bvh: Path = DEFAULT_BVH) -> Path | None:
    """Side and top views of the searched right-fist path and the captured punch (paper Fig. 4)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    capture = captured_punch(bvh)
    names = [str(n) for n in dataset["feature_names"]]
    fist = dataset["features"][:, names.index("fist_r_pos_x"):names.index("fist_r_pos_z") + 1] - CHARACTER_RIGHT_SHOULDER
    figure, (side_view, top_view) = plt.subplots(1, 2, figsize=(10, 4.2))
    for path, label, color in [(fist, "searched fist (right)", "tab:red"),
                               (capture["hand"], f"captured {str(capture['side']).lower()} hand, CMU 143/23", "black")]:
        side_view.plot(path[:, 2], path[:, 1], color=color, label=label)
        side_view.scatter(path[0, 2], path[0, 1], color=color, s=15)
        top_view.plot(path[:, 2], path[:, 0], color=color, label=label)
        top_view.scatter(path[0, 2], path[0, 0], color=color, s=15)
    side_view.set_xlabel("forward from the shoulder (m)")
    side_view.set_ylabel("up from the shoulder (m)")
    top_view.set_xlabel("forward from the shoulder (m)")
    top_view.set_ylabel("left of the shoulder (m)")
    for axis in (side_view, top_view):
        axis.set_aspect("equal", adjustable="datalim")
        axis.grid(alpha=0.3)
    side_view.legend(fontsize=8)
    figure.suptitle(f"Fist path against motion capture (aligned at the shoulder, scaled to a {CHARACTER_ARM_LENGTH_M} m arm)")
    figure.tight_layout()
    path = out / "fist_vs_capture.png"
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
