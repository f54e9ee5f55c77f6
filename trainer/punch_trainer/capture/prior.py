"""The captured punches retargeted onto the character's joints: a prior from motion capture (experiments/notebook.md,
"The captured punches as the search's start, and tracked").

A captured punch (capture/punches.py: CMU 143/23, turned so that its reach points at +Z with +X the boxer's
left, as the character's frame) becomes, for the trunk and the punching arm, each joint's rotation since the
guard, taken as the capture's pose at movement onset, in its parent's frame: the trunk relative to the hips
(flexion about X, turn about Y), the upper arm relative to the trunk (the rotation vector's X, Y and Z: flexion,
rotation, abduction, from the upper arm's direction and the plane of the forearm) and the elbow's opening. These
are the signs of the action table in docs/env.md (a forward flexion of the shoulder is negative, the trunk turning
left positive). The guard arm stays at its guard. As actions, each angle is a share of the joint's range, so the
action sequence can start a trajectory search (`placement_search(init_mu=...)`). The capture ships with the
trainer (punch_trainer/data, `capture.bvh.DEFAULT_BVH`); this module sits with its reading (the `capture`
layer), below the search (learn) it can start."""

from __future__ import annotations

import numpy as np

from punch_trainer.capture.punches import CapturedPunch, angle_between
from punch_trainer.errors import PunchError

CAPTURED_JOINTS = ("waist_flexion", "waist_rotation", "shoulder_r_flexion", "shoulder_r_rotation",
                   "shoulder_r_abduction", "elbow_r_extension")
"""the joints a captured punch gives, the first six of the action order (punch_core::character::DOFS)"""


class CapturePriorError(PunchError):
    """A character whose actions do not start with the joints a captured punch gives."""


def _unit(v: np.ndarray) -> np.ndarray:
    return np.asarray(v / np.linalg.norm(v, axis=-1, keepdims=True))


def _frames(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Rotations [frames, 3, 3] whose columns are x made orthogonal to y, y, and x cross y."""
    y = _unit(y)
    x = _unit(x - np.sum(x * y, axis=-1, keepdims=True) * y)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def _rotation_vector(m: np.ndarray) -> np.ndarray:
    """The rotation vectors [frames, 3] of rotations [frames, 3, 3] (angles below pi)."""
    angle = np.arccos(np.clip((np.trace(m, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0))
    axis = np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], axis=-1)
    sine = np.sin(angle)[..., None]
    return np.where(sine > 1e-6, axis * angle[..., None] / (2.0 * np.maximum(sine, 1e-6)), 0.0)


def captured_joint_angles(punch: CapturedPunch) -> np.ndarray:
    """The six joints of `CAPTURED_JOINTS` over the punch's frames, [frames, 6] (rad), 0 at movement onset."""
    joint = punch.joint
    frames = len(punch.positions)
    hips = _frames(joint("LeftUpLeg") - joint("RightUpLeg"), np.tile([0.0, 1.0, 0.0], (frames, 1)))
    trunk = _frames(joint("LeftArm") - joint("RightArm"), joint("Neck") - joint("LowerBack"))
    upper_arm = joint("RightForeArm") - joint("RightArm")
    forearm = joint("RightHand") - joint("RightForeArm")
    arm = _frames(np.cross(upper_arm, forearm), upper_arm)
    trunk_on_hips = np.einsum("fji,fjk->fik", hips, trunk)
    arm_on_trunk = np.einsum("fji,fjk->fik", trunk, arm)
    onset = punch.onset
    # A joint's rotation since the guard, in its parent's frame: Q(t) Q(onset)^T.
    waist = _rotation_vector(np.einsum("fij,kj->fik", trunk_on_hips, trunk_on_hips[onset]))
    shoulder = _rotation_vector(np.einsum("fij,kj->fik", arm_on_trunk, arm_on_trunk[onset]))
    elbow_opening = angle_between(-upper_arm, forearm)
    return np.column_stack([waist[:, 0], waist[:, 1], shoulder, elbow_opening - elbow_opening[onset]])


def captured_actions(punch: CapturedPunch, action_names: list[str], lower_rad: list[float], upper_rad: list[float],
                     decisions: int, decision_period: int, physics_hz: float, lead_decisions: int = 1) -> np.ndarray:
    """The punch as raw actions [decisions, len(action_names)] for a character whose actions are `action_names`
    with those limits (the server's `ServerInfo`), the first decision at movement onset: each decision
    asks for the pose the capture reaches `lead_decisions` decisions after that decision ends (the motors and the
    smoothing lag their targets), as a share of the joint's range (docs/env.md: a > 0 moves to a x the upper
    limit); joints the capture does not give hold the guard (0)."""
    if tuple(action_names[:len(CAPTURED_JOINTS)]) != CAPTURED_JOINTS:
        raise CapturePriorError(f"the character's actions start {action_names[:len(CAPTURED_JOINTS)]}, not {list(CAPTURED_JOINTS)}")
    angles = captured_joint_angles(punch)
    capture_frames_per_physics_frame = 1.0 / (physics_hz * punch.frame_time_s)
    physics_frames = decision_period * (np.arange(decisions) + 1 + lead_decisions)
    frames = np.minimum(punch.onset + np.round(physics_frames * capture_frames_per_physics_frame).astype(int), len(angles) - 1)
    pose = angles[frames]
    count = len(CAPTURED_JOINTS)
    actions = np.zeros((decisions, len(action_names)))
    actions[:, :count] = np.where(pose > 0, pose / np.asarray(upper_rad[:count]), pose / -np.asarray(lower_rad[:count]))
    return np.clip(actions, -1.0, 1.0)
