"""The four punches of the motion capture (CMU 143/23, `capture.bvh`): where each starts, reaches and ends, and
its joints' positions in a frame turned toward its reach and scaled to the character's arm (docs/naturalness.md,
"The capture"). `report/naturalness.py` measures them as it measures a simulated punch; `capture.prior`
retargets them onto the character's joints."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from punch_trainer.capture.bvh import CHARACTER_ARM_LENGTH_M, DEFAULT_BVH, joint_positions, read_bvh

CAPTURE_REACH_FRAMES = (140, 317, 509, 695)
"""frames of the capture near which the right hand is at full reach (punch_trainer/data/README.md)"""
ONSET_SPEED_FRACTION = 0.15
"""movement onset: the hand's speed last rises above this fraction of its peak before full reach"""
CAPTURE_SEARCH_S = 0.35
"""the capture's onset and speed peak are looked for in this long a window before full reach"""
CAPTURE_LEAD_S = 0.2
"""a captured punch's joint positions start this long before its onset (for the plots and the trunk's wind-up)"""
CAPTURE_RETURN_AFTER_S = 0.1
"""the capture's whole punch ends at the first frame this long after full reach where the hand is slow again"""


def speeds_from_positions(points: np.ndarray, dt_s: float) -> np.ndarray:
    """Speed between consecutive frames (forward differences), [frames - 1]."""
    return np.asarray(np.linalg.norm(np.diff(points, axis=0), axis=1) / dt_s, dtype=np.float64)


@dataclass(frozen=True)
class CapturedPunch:
    """One punch of the capture, in the capture's world frame turned about the vertical so the punching hand's
    reach (its position at full reach minus the right shoulder's at onset, horizontally) points at +Z, +X the
    boxer's left, +Y up, and scaled from the file's units to the character's arm (`CHARACTER_ARM_LENGTH_M`)."""

    onset: int
    """frame of movement onset, in `positions`' own frames"""
    reach: int
    """frame of full reach"""
    end: int
    """frame where the hand is slow again after pulling back: the end of the whole punch"""
    frame_time_s: float
    positions: np.ndarray
    """[frames, joints, 3] (m), from `CAPTURE_LEAD_S` before `onset` to `end`"""
    names: list[str]

    def joint(self, name: str) -> np.ndarray:
        return self.positions[:, self.names.index(name)]


def captured_punches(path: Path = DEFAULT_BVH) -> list[CapturedPunch]:
    """The four right-hand punches of the capture (docs/naturalness.md, "The capture")."""
    skeleton = read_bvh(path)
    world = joint_positions(skeleton)
    names = skeleton.names
    index = names.index
    arm_length = float(np.linalg.norm(skeleton.offsets[index("RightForeArm")]) + np.linalg.norm(skeleton.offsets[index("RightHand")]))
    scaled = world * (CHARACTER_ARM_LENGTH_M / arm_length)
    dt = skeleton.frame_time_s
    hand, shoulder = scaled[:, index("RightHand")], scaled[:, index("RightArm")]
    reach_distance = np.linalg.norm(hand - shoulder, axis=1)
    speed = speeds_from_positions(hand, dt)  # speed[k]: from frame k to k + 1
    punches = []
    for near in CAPTURE_REACH_FRAMES:
        reach = near - 15 + int(np.argmax(reach_distance[near - 15:near + 16]))
        first = max(1, reach - int(round(CAPTURE_SEARCH_S / dt)))  # frame 0 is the T-pose
        window = speed[first:reach]
        peak = int(np.argmax(window))
        threshold = ONSET_SPEED_FRACTION * float(window.max())
        onset = peak
        while onset > 0 and window[onset - 1] >= threshold:
            onset -= 1
        onset += first
        end = reach + int(round(CAPTURE_RETURN_AFTER_S / dt))
        while end < len(speed) - 1 and speed[end] >= threshold:
            end += 1
        direction = (hand[reach] - shoulder[onset]) * [1.0, 0.0, 1.0]
        angle = np.arctan2(direction[0], direction[2])
        c, s = np.cos(angle), np.sin(angle)
        turn = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
        start = max(1, onset - int(round(CAPTURE_LEAD_S / dt)))
        positions = scaled[start:end + 1] @ turn.T
        punches.append(CapturedPunch(onset - start, reach - start, end - start, dt, positions, names))
    return punches


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle (rad) between vectors a and b [..., 3], per row."""
    cosine = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.asarray(np.arccos(np.clip(cosine, -1.0, 1.0)), dtype=np.float64)
