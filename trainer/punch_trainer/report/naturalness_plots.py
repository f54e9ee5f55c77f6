"""Pictures of the naturalness report (docs/naturalness.md): the paper's Fig. 4 with both fists and the trunk of
a policy's punches against the four captured ones, and a strip of stick figures, a captured punch above the
policy's, a few frames across each punch. Matplotlib only, into PNG files."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from punch_trainer.capture.punches import CapturedPunch
from punch_trainer.report.naturalness import contact_frame, trunk_lean_deg

plt.switch_backend("Agg")  # files only, no display

# The character's rest pose (godot_project/tools/build_scenes.gd, docs/env.md): joint centres in the character's
# frame, and the bones of the arms.
WAIST = np.array([0.0, 1.056, 0.0])
NECK = np.array([0.0, 1.42, 0.0])
HEAD = np.array([0.0, 1.58, 0.0])
SHOULDER_HALF_WIDTH_M = 0.18
UPPER_ARM_M = 0.282
FOREARM_TO_FIST_M = 0.269 + 0.068
_UPPER_DIRECTION = np.array([0.0, -np.cos(np.radians(35.0)), np.sin(np.radians(35.0))])
# The legs do not move (the pelvis is fixed): drawn for the picture only.
_LEGS = {"hip_r": [-0.09, 0.95, 0.0], "knee_r": [-0.1, 0.5, 0.03], "foot_r": [-0.11, 0.05, 0.0],
         "hip_l": [0.09, 0.95, 0.0], "knee_l": [0.1, 0.5, 0.03], "foot_l": [0.11, 0.05, 0.0]}

POLICY_JOINTS = ["waist", "neck", "head", "shoulder_r", "elbow_r", "fist_r", "shoulder_l", "elbow_l", "fist_l", *_LEGS]
BONES = [("waist", "neck"), ("neck", "head"), ("neck", "shoulder_r"), ("shoulder_r", "elbow_r"), ("elbow_r", "fist_r"),
         ("neck", "shoulder_l"), ("shoulder_l", "elbow_l"), ("elbow_l", "fist_l"), ("waist", "hip_r"), ("hip_r", "knee_r"),
         ("knee_r", "foot_r"), ("waist", "hip_l"), ("hip_l", "knee_l"), ("knee_l", "foot_l")]
CAPTURE_JOINTS = {"waist": "LowerBack", "neck": "Neck", "head": "Head", "shoulder_r": "RightArm", "elbow_r": "RightForeArm",
                  "fist_r": "RightHand", "shoulder_l": "LeftArm", "elbow_l": "LeftForeArm", "fist_l": "LeftHand",
                  "hip_r": "RightUpLeg", "knee_r": "RightLeg", "foot_r": "RightFoot", "hip_l": "LeftUpLeg",
                  "knee_l": "LeftLeg", "foot_l": "LeftFoot"}


def _rotation(vector: np.ndarray) -> np.ndarray:
    """The rotation matrix of a rotation vector (axis times angle, rad)."""
    angle = float(np.linalg.norm(vector))
    if angle < 1e-12:
        return np.eye(3)
    x, y, z = vector / angle
    cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.asarray(np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross, dtype=np.float64)


def _elbow(shoulder: np.ndarray, fist: np.ndarray, guess: np.ndarray) -> np.ndarray:
    """The point at the upper arm's length from the shoulder and the forearm's from the fist nearest `guess`."""
    offset = fist - shoulder
    distance = float(np.linalg.norm(offset))
    if distance < 1e-9:
        return guess
    axis = offset / distance
    if distance >= UPPER_ARM_M + FOREARM_TO_FIST_M or distance <= abs(UPPER_ARM_M - FOREARM_TO_FIST_M):
        return shoulder + UPPER_ARM_M * axis if distance >= UPPER_ARM_M else guess
    along = (UPPER_ARM_M ** 2 - FOREARM_TO_FIST_M ** 2 + distance ** 2) / (2 * distance)
    radius = np.sqrt(max(UPPER_ARM_M ** 2 - along ** 2, 0.0))
    centre = shoulder + along * axis
    away = guess - centre
    away = away - (away @ axis) * axis
    if np.linalg.norm(away) < 1e-9:
        away = np.cross(axis, [1.0, 0.0, 0.0])
    return np.asarray(centre + radius * away / np.linalg.norm(away), dtype=np.float64)


def policy_skeleton(features: np.ndarray, names: list[str]) -> np.ndarray:
    """Joint positions [frames, len(POLICY_JOINTS), 3] of a simulated punch in the character's frame: the fists
    as measured; the neck, head and shoulders turned about the waist by its two angles; each elbow where both
    arm bones keep their length between the shoulder and the measured fist, on the side the shoulder's angles
    put it (the constraints' locked axes give a little, so the angles alone miss the fist by up to ~10 cm)."""
    col = names.index
    frames = []
    for row in np.asarray(features, dtype=np.float64):
        angles = {name.removeprefix("angle_"): float(row[col(name)]) for name in names if name.startswith("angle_")}

        torso = _rotation(np.array([angles["waist_flexion"], angles["waist_rotation"], 0.0]))
        joints = {"waist": WAIST, "neck": WAIST + torso @ (NECK - WAIST), "head": WAIST + torso @ (HEAD - WAIST)}
        for side, sign in (("r", -1.0), ("l", 1.0)):
            rest_shoulder = np.array([sign * SHOULDER_HALF_WIDTH_M, NECK[1], 0.0])
            shoulder = WAIST + torso @ (rest_shoulder - WAIST)
            upper = torso @ _rotation(np.array([angles[f"shoulder_{side}_flexion"], angles[f"shoulder_{side}_rotation"],
                                                angles[f"shoulder_{side}_abduction"]]))
            fist = row[col(f"fist_{side}_pos_x"):col(f"fist_{side}_pos_z") + 1]
            joints.update({f"shoulder_{side}": shoulder, f"fist_{side}": fist,
                           f"elbow_{side}": _elbow(shoulder, fist, shoulder + upper @ (UPPER_ARM_M * _UPPER_DIRECTION))})
        joints.update({name: np.array(point) for name, point in _LEGS.items()})
        frames.append([joints[name] for name in POLICY_JOINTS])
    return np.array(frames)


def capture_skeleton(punch: CapturedPunch) -> np.ndarray:
    """Joint positions [frames, len(POLICY_JOINTS), 3] of a captured punch, moved so the lower back starts above
    the origin and the lower foot on the floor (y = 0)."""
    points = np.stack([punch.joint(CAPTURE_JOINTS[name]) for name in POLICY_JOINTS], axis=1)
    start = points[punch.onset]
    shift = np.array([start[0, 0], min(start[POLICY_JOINTS.index("foot_r"), 1], start[POLICY_JOINTS.index("foot_l"), 1]), start[0, 2]])
    return np.asarray(points - shift, dtype=np.float64)


def _frames_across(first: int, last: int, count: int) -> list[int]:
    return [int(round(v)) for v in np.linspace(first, last, count)]


def plot_stick_strip(out: Path, features: np.ndarray, names: list[str], physics_hz: float, capture: CapturedPunch, *, columns: int = 5,
                     file_name: str = "naturalness_strip.png") -> Path:
    """Stick figures, seen from the right and a little in front: the captured punch (movement onset to full reach) above the
    policy's (first frame to first contact), at `columns` evenly spaced moments of each."""
    policy = policy_skeleton(features, names)
    end, touched = contact_frame(np.asarray(features, dtype=np.float64), names)
    captured = capture_skeleton(capture)
    rows = [(f"captured punch, CMU 143/23 ({(capture.reach - capture.onset) * capture.frame_time_s:.2f} s onset to full reach)",
             captured, _frames_across(capture.onset, capture.reach, columns), "black"),
            (f"policy ({(end + 1) / physics_hz:.2f} s to {'contact' if touched else 'closest approach'})", policy,
             _frames_across(0, end, columns), "tab:red")]
    figure = plt.figure(figsize=(2.6 * columns, 7.0))
    for row, (title, points, moments, colour) in enumerate(rows):
        for column, frame in enumerate(moments):
            axis = figure.add_subplot(2, columns, row * columns + column + 1, projection="3d")
            pose = points[frame]
            for a, b in BONES:
                i, j = POLICY_JOINTS.index(a), POLICY_JOINTS.index(b)
                axis.plot([pose[i, 2], pose[j, 2]], [pose[i, 0], pose[j, 0]], [pose[i, 1], pose[j, 1]], color=colour, linewidth=2)
            for fist, fist_colour in (("fist_r", "tab:red"), ("fist_l", "tab:blue")):
                trail = points[:frame + 1, POLICY_JOINTS.index(fist)]
                axis.plot(trail[:, 2], trail[:, 0], trail[:, 1], color=fist_colour, linewidth=0.8, alpha=0.7)
            axis.plot([-0.3, 0.8, 0.8, -0.3, -0.3], [-0.4, -0.4, 0.4, 0.4, -0.4], [0, 0, 0, 0, 0], color="0.7", linewidth=0.8)
            axis.set_xlim(-0.3, 0.8)
            axis.set_ylim(-0.55, 0.55)
            axis.set_zlim(0.0, 1.75)
            axis.set_box_aspect((1.1, 1.1, 1.75))
            axis.view_init(elev=12, azim=-72)
            axis.set_axis_off()
            fraction = moments.index(frame) / max(columns - 1, 1)
            axis.set_title(f"{100 * fraction:.0f}%", fontsize=9, y=0.92)
        figure.text(0.5, 0.97 - 0.48 * row, title, ha="center", fontsize=11)
    figure.text(0.5, 0.01, "Seen from the right, a little in front; thin red: the right fist's path so far, blue: the left fist's", ha="center", fontsize=9)
    figure.subplots_adjust(left=0.0, right=1.0, bottom=0.03, top=0.95, wspace=0.0, hspace=0.12)
    path = out / file_name
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path


def plot_capture_comparison(out: Path, punches: np.ndarray, names: list[str], physics_hz: float, capture: list[CapturedPunch],
                            *, file_name: str = "naturalness_fig4.png", most: int = 32) -> Path:
    """The paper's Fig. 4, both fists and the trunk: a policy's punches (features [P, frames, F], up to `most`)
    against the four captured punches. Paths start at the punching shoulder's position in the first frame
    (captured: at movement onset), times at contact (captured: full reach); the capture is scaled to the
    character's arm (docs/naturalness.md)."""
    col = names.index
    figure, axes = plt.subplots(2, 3, figsize=(14, 8))
    (side, top, speed), (off_distance, off_side, trunk) = axes

    def draw(time_s: np.ndarray, until: int, hand: np.ndarray, off: np.ndarray, lean: np.ndarray, colour: str, alpha: float,
             label: str | None) -> None:
        hand_speed = np.linalg.norm(np.gradient(hand, time_s, axis=0), axis=1)
        side.plot(hand[:until + 1, 2], hand[:until + 1, 1], color=colour, alpha=alpha, linewidth=1, label=label)
        top.plot(hand[:until + 1, 2], hand[:until + 1, 0], color=colour, alpha=alpha, linewidth=1, label=label)
        speed.plot(time_s, hand_speed, color=colour, alpha=alpha, linewidth=1, label=label)
        off_distance.plot(time_s, np.linalg.norm(off, axis=1) * 100, color=colour, alpha=alpha, linewidth=1, label=label)
        off_side.plot(off[:until + 1, 2] * 100, off[:until + 1, 1] * 100, color=colour, alpha=alpha, linewidth=1, label=label)
        trunk.plot(time_s, lean, color=colour, alpha=alpha, linewidth=1, label=label)

    shown = np.asarray(punches[:most], dtype=np.float64)
    for index, features in enumerate(shown):
        end, _ = contact_frame(features, names)
        time_s = (np.arange(len(features)) - end) / physics_hz
        shoulder = policy_skeleton(features[:1], names)[0, POLICY_JOINTS.index("shoulder_r")]
        hand = features[:, col("fist_r_pos_x"):col("fist_r_pos_z") + 1] - shoulder
        off_fist = features[:, col("fist_l_pos_x"):col("fist_l_pos_z") + 1]
        draw(time_s, end, hand, off_fist - off_fist[0], np.degrees(features[:, col("angle_waist_flexion")]), "tab:red", 0.35,
             "policy (waist flexion)" if index == 0 else None)
    for index, punch in enumerate(capture):
        capture_time_s = (np.arange(len(punch.positions)) - punch.reach) * punch.frame_time_s
        hand = punch.joint("RightHand") - punch.joint("RightArm")[punch.onset]
        off = punch.joint("LeftHand") - punch.joint("LeftHand")[punch.onset]
        draw(capture_time_s[punch.onset:], punch.reach - punch.onset, hand[punch.onset:], off[punch.onset:], trunk_lean_deg(punch)[punch.onset:],
             "black", 0.8, "captured, CMU 143/23 (trunk lean from vertical)" if index == 0 else None)
    side.set(xlabel="forward from the shoulder (m)", ylabel="up from the shoulder (m)", title="punching (right) fist, side view")
    top.set(xlabel="forward from the shoulder (m)", ylabel="left of the shoulder (m)", title="punching fist, top view")
    speed.set(xlabel="time from contact / full reach (s)", ylabel="speed (m/s)", title="punching fist speed")
    off_distance.set(xlabel="time from contact / full reach (s)", ylabel="distance (cm)", title="off (left) fist: distance from its guard")
    off_side.set(xlabel="forward (cm)", ylabel="up (cm)", title="off fist from its guard, side view, until contact")
    trunk.set(xlabel="time from contact / full reach (s)", ylabel="degrees", title="trunk: forward flexion / lean")
    for axis in (side, top, off_side):
        axis.set_aspect("equal", adjustable="datalim")
    for axis in axes.flat:
        axis.grid(alpha=0.3)
    side.legend(fontsize=8)
    trunk.legend(fontsize=8)
    figure.suptitle(f"A policy's punches ({len(shown)}, sigma 0) against the four captured punches, aligned at the shoulder and at "
                    "contact, the capture scaled to the character's 0.619 m arm")
    figure.tight_layout()
    path = out / file_name
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return path
