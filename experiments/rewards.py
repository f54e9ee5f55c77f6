"""Rewards experiments tried and no shipped policy uses, each a `punch train --reward experiments/rewards.py:NAME`.

hook_sweep: the hook that sweeps in from the side, max(0, 0.3 - d)^2 * 10 * (a + 1.5 c), with a the right fist's
horizontal velocity along the line from its shoulder to the bag and c across it, toward the body's middle. At a given
speed the best direction lies 56 degrees off that line (docs/moves.md asks a hook at least 35). Tried in
notebook.md, "Moves from the stance's guard": it brings the hook in from the side and costs it accuracy. The
`hook_bent` preset (the stance's rear hook) is it with the landing impulse counted only with the elbow bent.

hook_level, hook_outside: `hook_bent` with a level swing asked for, or its landing counted only from outside the line:
tried for the lead hook (notebook.md, "A hook that sweeps with the elbow bent").

uppercut_soft: `uppercut_bent` with a quarter of its landing counted however the fist comes: tried for the lead
uppercut (notebook.md, "An uppercut that rises with the elbow bent").
"""

import numpy as np

from punch_trainer.reward.rewards import hook_bent, uppercut_bent
from punch_trainer.scene import shoulder_positions


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


def _sweep_axes(f):
    """The horizontal unit vector from the right shoulder to the bag (ux, uz), as `hook_sweep` reads it."""
    names = f.names
    frames = f.features.reshape(-1, len(names))
    shoulder = shoulder_positions(frames, names.index).reshape(*f.features.shape[:-1], 3)
    dx, dz = f["bag_pos_x"] - shoulder[..., 0], f["bag_pos_z"] - shoulder[..., 2]
    length = np.maximum(np.hypot(dx, dz), 1e-6)
    return dx / length, dz / length


def hook_level(f):
    """`hook_bent` (the preset) less the fist's vertical speed near the bag (10 max(0, 0.3 - d)^2 |v_y|): a hook
    swings level, neither down from above nor up from below."""
    terms = hook_bent(f)
    near = np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2
    return {**terms, "level": -near * 10.0 * np.abs(f["fist_r_vel_y"])}


def hook_outside(f):
    """`hook_bent` (the preset) whose landing also counts only for a fist coming from outside the line from its
    shoulder to the bag: none at 20 degrees off it or less, all of it from 35 (the fist's horizontal velocity the frame
    before, as the naturalness report reads the approach: the contact itself turns the fist)."""
    terms = hook_bent(f)
    ux, uz = _sweep_axes(f)
    vx, vz = f["fist_r_vel_x"], f["fist_r_vel_z"]
    vx = np.concatenate([vx[..., :1], vx[..., :-1]], axis=-1)
    vz = np.concatenate([vz[..., :1], vz[..., :-1]], axis=-1)
    angle_deg = np.degrees(np.arctan2(vx * uz - vz * ux, vx * ux + vz * uz))
    outside = np.clip((angle_deg - 20.0) / 15.0, 0.0, 1.0)
    return {**terms, "landing": terms["landing"] * outside}



def uppercut_soft(f):
    """`uppercut_bent` (the preset) whose landing counts a quarter even flat or with the arm long, all of it rising with
    the elbow bent: the lead uppercut learned from the preset landed on few targets (notebook.md, "An uppercut that
    rises with the elbow bent")."""
    return uppercut_bent(f, flat_landing=0.25)
