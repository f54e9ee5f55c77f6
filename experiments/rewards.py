"""Rewards experiments tried and no shipped policy uses, each a `punch train --reward experiments/rewards.py:NAME`.

hook_sweep: the hook that sweeps in from the side, max(0, 0.3 - d)^2 * 10 * (a + 1.5 c), with a the right fist's
horizontal velocity along the line from its shoulder to the bag and c across it, toward the body's middle. At a given
speed the best direction lies 56 degrees off that line (docs/moves.md asks a hook at least 35). Tried in
notebook.md, "Moves from the stance's guard": it brings the hook in from the side and costs it accuracy. The
`hook_bent` preset (the stance's rear hook) is it with the landing impulse counted only with the elbow bent.

hook_level: `hook_bent` with a level swing asked for: tried for the lead hook (notebook.md, "A hook that sweeps with the
elbow bent"); `hook_outside`, its landing counted only from outside the line, was tried here first and is a preset now.

hook_outside_gated: `hook_outside` with its sweep near the bag counted only from outside the line too, as the uppercut's
gated stage: the shipped lead hook earns `hook_outside`'s return from the sweep while arriving 11 degrees off the line
(notebook.md, "The lead hook from outside, all of it gated").

hook_hard: `hook_bent` with its landing counted twice (10 times the impulse along the sweep, with the elbow bent): a
fist that lands harder earns more against the approach near the bag, asked of the rear hook, whose fist is slower than
the cross's (notebook.md, "A block on the move, and the rear hook's load again").

uppercut_no_drop: `uppercut_gated` less the fist's fall near the bag (10 max(0, 0.3 - d)^2 max(0, -v_y)): the rear
uppercut's body shots touch the bag on the way down, which the `uppercut` reward its success is read with counts
against it (notebook.md, "A block on the move, and the rear hook's load again").

The uppercuts' `uppercut_bent`, `uppercut_gated` and `uppercut_rising` presets were tried here first (notebook.md, "An
uppercut that rises with the elbow bent" and "A braced guard"): from scratch A2C kept the fist away; from a trained
uppercut they reshape it.
"""

import numpy as np

from punch_trainer.reward.rewards import along_target, hook_bent, hook_outside, uppercut_gated


def hook_sweep(f):
    ux, uz = along_target(f)  # from the shoulder the naturalness report reads
    near = np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2
    vx, vz = f["fist_r_vel_x"], f["fist_r_vel_z"]
    return {"along": near * 10.0 * (vx * ux + vz * uz), "across": near * 10.0 * 1.5 * (vx * uz - vz * ux)}


def hook_level(f):
    """`hook_bent` (the preset) less the fist's vertical speed near the bag (10 max(0, 0.3 - d)^2 |v_y|): a hook
    swings level, neither down from above nor up from below."""
    terms = hook_bent(f)
    near = np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2
    return {**terms, "level": -near * 10.0 * np.abs(f["fist_r_vel_y"])}


def hook_outside_gated(f):
    """`hook_outside` (the preset) whose sweep near the bag counts only while the fist moves from outside the line
    from its shoulder to the bag: none at 20 degrees off it or less, all from 35, as its landing."""
    terms = hook_outside(f)
    ux, uz = along_target(f)
    vx, vz = f["fist_r_vel_x"], f["fist_r_vel_z"]
    angle_deg = np.degrees(np.arctan2(vx * uz - vz * ux, vx * ux + vz * uz))
    return {**terms, "sweep": terms["sweep"] * np.clip((angle_deg - 20.0) / 15.0, 0.0, 1.0)}


def hook_hard(f):
    terms = hook_bent(f)
    return {**terms, "landing": 2.0 * terms["landing"]}


def uppercut_no_drop(f):
    near = np.maximum(0.0, 0.3 - f["fist_r_bag_distance"]) ** 2
    return {**uppercut_gated(f), "drop": -near * 10.0 * np.maximum(0.0, -f["fist_r_vel_y"])}
