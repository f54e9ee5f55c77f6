"""The motion-capture file and its reading: a BVH skeleton, every joint's world position, and the captured punch
whose hand path the paper's Fig. 4 sets against a searched fist path (relative to the punching shoulder, scaled
by arm length).

The clip is the CMU Graphics Lab Motion Capture Database's subject 143, trial 23 ("Punching"), in its BVH
conversion, shipped with the trainer (`punch_trainer/data/cmu_143_23.bvh`, its README says where from and what
it holds): 120 frames/s, ZYX Euler channels, frame 0 a T-pose."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

DEFAULT_BVH = Path(__file__).resolve().parents[1] / "data" / "cmu_143_23.bvh"
"""the capture, package data of `punch_trainer` (so an installed `punch` has it too)"""
# Shoulder joint to fist centre of the simulated character (docs/env.md).
CHARACTER_ARM_LENGTH_M = 0.619
CHARACTER_RIGHT_SHOULDER = np.array([-0.18, 1.42, 0.0])


@dataclass
class Skeleton:
    names: list[str]
    parents: list[int]
    offsets: np.ndarray  # [joints, 3]
    channels: list[list[str]]
    frame_time_s: float
    motion: np.ndarray  # [frames, channels]


def read_bvh(path: Path) -> Skeleton:
    tokens = path.read_text().split()
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[list[str]] = []
    stack: list[int] = []
    i = tokens.index("HIERARCHY") + 1
    while tokens[i] != "MOTION":
        token = tokens[i]
        if token in ("ROOT", "JOINT"):
            names.append(tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            i += 2
        elif token == "End":  # an end site: a joint with no channels
            names.append(names[stack[-1]] + "_end")
            parents.append(stack[-1])
            channels.append([])
            i += 2
        elif token == "{":
            stack.append(len(names) - 1)
            i += 1
        elif token == "}":
            stack.pop()
            i += 1
        elif token == "OFFSET":
            offsets.append([float(v) for v in tokens[i + 1:i + 4]])
            i += 4
        elif token == "CHANNELS":
            count = int(tokens[i + 1])
            channels.append(tokens[i + 2:i + 2 + count])
            i += 2 + count
        else:
            raise ValueError(f"{path}: unexpected token '{token}'")
    frames = int(tokens[i + 2])
    frame_time = float(tokens[i + 5])
    values = np.array(tokens[i + 6:], dtype=float)
    return Skeleton(names, parents, np.array(offsets), channels, frame_time, values.reshape(frames, -1))


def _rotation(axis: str, degrees: np.ndarray) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    one, zero = np.ones_like(c), np.zeros_like(c)
    rows = {"X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
            "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
            "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]]}[axis]
    return np.moveaxis(np.array(rows), [0, 1], [-2, -1])


def joint_positions(skeleton: Skeleton) -> np.ndarray:
    """World positions of every joint in every frame, [frames, joints, 3] (the file's units)."""
    frames = skeleton.motion.shape[0]
    count = len(skeleton.names)
    rotations = np.zeros((frames, count, 3, 3))
    positions = np.zeros((frames, count, 3))
    column = 0
    for joint in range(count):
        local_rotation = np.broadcast_to(np.eye(3), (frames, 3, 3)).copy()
        translation = np.broadcast_to(skeleton.offsets[joint], (frames, 3)).copy()
        for channel in skeleton.channels[joint]:
            values = skeleton.motion[:, column]
            column += 1
            if channel.endswith("position"):
                translation[:, "XYZ".index(channel[0])] += values
            else:
                local_rotation = local_rotation @ _rotation(channel[0], values)
        parent = skeleton.parents[joint]
        if parent < 0:
            rotations[:, joint], positions[:, joint] = local_rotation, translation
        else:
            positions[:, joint] = positions[:, parent] + np.einsum("fij,fj->fi", rotations[:, parent], translation)
            rotations[:, joint] = rotations[:, parent] @ local_rotation
    return positions


def captured_punch(path: Path = DEFAULT_BVH, reach_frame: int = 140, lead_s: float = 0.35) -> dict[str, np.ndarray]:
    """The punch that reaches full extension at `reach_frame`, from `lead_s` before it: the punching hand
    relative to its shoulder, rotated so the reach points at +Z (x the body's left, y up), and scaled to the
    character's arm length. Also returns the time axis (s) and the hand's peak speed (m/s, scaled)."""
    skeleton = read_bvh(path)
    positions = joint_positions(skeleton)
    index = skeleton.names.index
    best = None
    for side in ("Right", "Left"):
        shoulder, elbow, hand = index(f"{side}Arm"), index(f"{side}ForeArm"), index(f"{side}Hand")
        arm_length = float(np.linalg.norm(skeleton.offsets[elbow]) + np.linalg.norm(skeleton.offsets[hand]))
        reach = np.linalg.norm(positions[reach_frame, hand] - positions[reach_frame, shoulder]) / arm_length
        if best is None or reach > best[0]:
            best = (reach, side, shoulder, hand, arm_length)
    assert best is not None  # both sides were measured
    _, side, shoulder, hand, arm_length = best
    start = max(1, reach_frame - int(round(lead_s / skeleton.frame_time_s)))  # frame 0 is the T-pose
    relative = positions[start:reach_frame + 1, hand] - positions[start:reach_frame + 1, shoulder]
    direction = relative[-1] * [1, 0, 1]
    angle = np.arctan2(direction[0], direction[2])  # rotate about y so the reach points at +z
    c, s = np.cos(angle), np.sin(angle)
    turned = relative @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]).T
    scaled = turned / arm_length * CHARACTER_ARM_LENGTH_M
    speed = np.linalg.norm(np.diff(scaled, axis=0), axis=1) / skeleton.frame_time_s
    return {"hand": scaled, "time_s": np.arange(len(scaled)) * skeleton.frame_time_s, "side": np.array(side),
            "peak_speed_mps": np.array(speed.max())}
