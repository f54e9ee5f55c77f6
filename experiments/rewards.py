"""Rewards experiments tried and no shipped policy uses, each a `punch train --reward experiments/rewards.py:NAME`.

hook_sweep: the hook that sweeps in from the side, max(0, 0.3 - d)^2 * 10 * (a + 1.5 c), with a the right fist's
horizontal velocity along the line from its shoulder to the bag and c across it, toward the body's middle. At a given
speed the best direction lies 56 degrees off that line (docs/moves.md asks a hook at least 35). Tried in
notebook.md, "Moves from the stance's guard": it brings the hook in from the side and costs it accuracy.
"""

import numpy as np

from punch_trainer.report.naturalness import shoulder_positions


def hook_sweep(f):
    names = f.names
    frames = f.features.reshape(-1, len(names))
    shoulder = shoulder_positions(frames, names.index).reshape(*f.features.shape[:-1], 3)  # the naturalness report's
    dx, dz = f["bag_pos_x"] - shoulder[..., 0], f["bag_pos_z"] - shoulder[..., 2]
    length = np.maximum(np.hypot(dx, dz), 1e-6)
    ux, uz = dx / length, dz / length
    near = np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2
    vx, vz = f["fist_r_vel_x"], f["fist_r_vel_z"]
    return {"along": near * 10.0 * (vx * ux + vz * uz), "across": near * 10.0 * 1.5 * (vx * uz - vz * ux)}
