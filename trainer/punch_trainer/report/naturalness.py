"""How much a punch looks like a person's: the naturalness figures of docs/naturalness.md, computed from one
punch's per-frame features (the character's frame: +Z toward the bag, +X the character's left, +Y up), and
the same figures of the four punches of the motion capture (CMU 143/23, `capture.punches`), for the tables of
`punch eval` and `punch train`.

Every figure of a simulated punch runs from the episode's first frame to the right fist's first contact with
the bag (its closest approach when it never touches); the off fist's distance from its guard and its peak
speed are also given over the whole episode. A captured punch runs from movement onset to full reach
(`CapturedPunch`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from punch_trainer.capture.bvh import DEFAULT_BVH
from punch_trainer.capture.punches import CapturedPunch, angle_between, captured_punches, speeds_from_positions
from punch_trainer.reward.rewards import first_right_contact
from punch_trainer.reward.style import chain_speeds
from punch_trainer.scene import GUARD_ELBOW_BEND_DEG, shoulder_positions


@dataclass(frozen=True)
class PunchNaturalness:
    """The figures of one punch (docs/naturalness.md). Distances in m, speeds in m/s, times in s."""

    path_over_chord: float
    """punching fist's path length / the straight distance from its first to its last position"""
    chord_distance_m: float
    """punching fist's largest distance from that chord (the segment from its first to its last position)"""
    off_fist_from_guard_m: float
    """off (left) fist's largest distance from its position in the first frame, until contact"""
    off_fist_from_guard_whole_m: float
    """the same over the whole punch"""
    off_fist_peak_speed_mps: float
    """off fist's peak speed until contact"""
    off_fist_peak_speed_whole_mps: float
    """the same over the whole punch"""
    trunk_flexion_deg: float
    """largest waist flexion until contact (simulated: angle_waist_flexion; captured: trunk lean from vertical)"""
    trunk_flexion_whole_deg: float
    """the same over the whole punch"""
    fist_peak_speed_mps: float
    """punching fist's peak speed until contact"""
    proximal_to_distal: bool
    """waist rotation, then shoulder, then elbow reach their peak speed, in that order (ties count as in order)"""
    time_to_contact_s: float | None
    """from the first frame (captured: movement onset) to contact (captured: full reach); None without contact"""
    side_angle_at_contact_deg: float | None = None
    """the horizontal angle between the punching fist's velocity at contact and the line from its shoulder to the
    target (0: straight down that line; a hook arrives from the side); None for a captured punch, still at full reach"""
    rise_share_at_contact: float | None = None
    """the upward part of the punching fist's velocity at contact over its speed (an uppercut rises into the target)"""
    elbow_bend_at_contact_deg: float | None = None
    """the punching elbow's bend at contact (captured: full reach), 0 straight, 90 a right angle"""

    def to_json(self) -> dict[str, float | bool | None]:
        return asdict(self)


@dataclass(frozen=True)
class Figure:
    """One row of the naturalness table."""

    key: str
    label: str
    scale: float
    unit: str
    digits: int


FIGURES = (
    Figure("path_over_chord", "punching fist path length / chord", 1.0, "", 2),
    Figure("chord_distance_m", "punching fist's largest distance from that chord", 100.0, " cm", 1),
    Figure("off_fist_from_guard_m", "off fist's largest distance from its guard, by contact", 100.0, " cm", 1),
    Figure("off_fist_from_guard_whole_m", "off fist's largest distance from its guard, whole punch", 100.0, " cm", 1),
    Figure("off_fist_peak_speed_mps", "off fist peak speed, by contact", 1.0, " m/s", 2),
    Figure("off_fist_peak_speed_whole_mps", "off fist peak speed, whole punch", 1.0, " m/s", 2),
    Figure("trunk_flexion_deg", "largest waist flexion (captured: trunk lean from vertical), by contact", 1.0, "°", 1),
    Figure("trunk_flexion_whole_deg", "largest waist flexion (captured: trunk lean), whole punch", 1.0, "°", 1),
    Figure("fist_peak_speed_mps", "punching fist peak speed", 1.0, " m/s", 2),
    Figure("time_to_contact_s", "time to contact (captured: onset to full reach)", 1.0, " s", 3),
    Figure("side_angle_at_contact_deg", "fist's approach from the side at contact (velocity against shoulder-to-target line)", 1.0, "°", 0),
    Figure("rise_share_at_contact", "rising share of the fist's velocity at contact", 1.0, "", 2),
    Figure("elbow_bend_at_contact_deg", "elbow bend at contact (captured: full reach)", 1.0, "°", 0),
)


# --- geometry of a path -------------------------------------------------------------------------------------

def path_over_chord(points: np.ndarray) -> float:
    """Length of the path through `points` [frames, 3] over the distance from its first to its last point
    (1 for a straight path; inf when it ends where it started)."""
    length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    chord = float(np.linalg.norm(points[-1] - points[0]))
    return length / chord if chord > 0 else float("inf")


def largest_distance_from_chord(points: np.ndarray) -> float:
    """Largest distance of `points` [frames, 3] from the segment joining the first and the last point."""
    start, end = points[0], points[-1]
    chord = end - start
    squared = float(chord @ chord)
    along = np.clip((points - start) @ chord / squared, 0.0, 1.0) if squared > 0 else np.zeros(len(points))
    return float(np.linalg.norm(points - (start + along[:, None] * chord), axis=1).max())


def largest_distance_from_start(points: np.ndarray) -> float:
    """Largest distance of `points` [frames, 3] from the first of them."""
    return float(np.linalg.norm(points - points[0], axis=1).max())


def in_proximal_to_distal_order(waist: np.ndarray, shoulder: np.ndarray, elbow: np.ndarray) -> bool:
    """Whether the peaks of |waist|, |shoulder| and |elbow| (speeds over the same frames) come in that order."""
    waist_peak, shoulder_peak, elbow_peak = (int(np.abs(s).argmax()) for s in (waist, shoulder, elbow))
    return waist_peak <= shoulder_peak <= elbow_peak


# --- a simulated punch ----------------------------------------------------------------------------------------

def horizontal_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between the horizontal (x, z) parts of two vectors, degrees (0 when either has none)."""
    a, b = np.array([a[0], a[2]]), np.array([b[0], b[2]])
    norms = float(np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(a @ b / norms, -1.0, 1.0)))) if norms > 0 else 0.0


def contact_frame(features: np.ndarray, names: list[str]) -> tuple[int, bool]:
    """The right fist's first contact frame of features [frames, F], or, when it never touches, the frame of its
    closest approach to the bag; and whether it touched."""
    hit, first = first_right_contact(features, names)
    if bool(hit):
        return int(first), True
    return int(np.argmin(features[:, names.index("fist_r_bag_distance")])), False


def punch_naturalness(features: np.ndarray, names: list[str], physics_hz: float) -> PunchNaturalness:
    """The figures of one simulated punch, features [frames, F] in the character's frame (docs/naturalness.md)."""
    f = np.asarray(features, dtype=np.float64)
    col = names.index
    end, touched = contact_frame(f, names)
    until = slice(0, end + 1)

    def vector(stem: str) -> np.ndarray:
        return f[:, col(f"{stem}_x"):col(f"{stem}_z") + 1]

    fist, off, off_velocity = vector("fist_r_pos"), vector("fist_l_pos"), vector("fist_l_vel")
    fist_speed = np.linalg.norm(vector("fist_r_vel"), axis=1)
    off_speed = np.linalg.norm(off_velocity, axis=1)
    # The chain's speeds as the order style reads them in training (reward/style.py), so the two cannot drift.
    waist, shoulder, elbow = chain_speeds(lambda name: f[:, col(name)])
    # The approach: the frame before the contact, whose impulse has already turned the fist.
    approach = max(end - 1, 0)
    velocity_at_end, target_at_end = vector("fist_r_vel")[approach], vector("bag_pos")[approach]
    speed_at_end = float(np.linalg.norm(velocity_at_end))
    return PunchNaturalness(
        path_over_chord=path_over_chord(fist[until]) if end > 0 else 1.0,
        chord_distance_m=largest_distance_from_chord(fist[until]),
        off_fist_from_guard_m=largest_distance_from_start(off[until]),
        off_fist_from_guard_whole_m=largest_distance_from_start(off),
        off_fist_peak_speed_mps=float(off_speed[until].max()),
        off_fist_peak_speed_whole_mps=float(off_speed.max()),
        trunk_flexion_deg=float(np.degrees(f[until, col("angle_waist_flexion")].max())),
        trunk_flexion_whole_deg=float(np.degrees(f[:, col("angle_waist_flexion")].max())),
        fist_peak_speed_mps=float(fist_speed[until].max()),
        proximal_to_distal=in_proximal_to_distal_order(waist[until], shoulder[until], elbow[until]),
        time_to_contact_s=(end + 1) / physics_hz if touched else None,
        side_angle_at_contact_deg=horizontal_angle_deg(velocity_at_end, target_at_end - shoulder_positions(f[approach:approach + 1], col)[0]),
        rise_share_at_contact=float(velocity_at_end[1] / speed_at_end) if speed_at_end > 0 else 0.0,
        elbow_bend_at_contact_deg=GUARD_ELBOW_BEND_DEG - float(np.degrees(f[end, col("angle_elbow_r_extension")])),
    )


def punches_naturalness(features: np.ndarray, names: list[str], physics_hz: float) -> list[PunchNaturalness]:
    """`punch_naturalness` of every punch of features [punches, frames, F]."""
    return [punch_naturalness(np.asarray(punch), names, physics_hz) for punch in features]


@dataclass(frozen=True)
class NaturalnessSummary:
    """Medians of the figures over punches, and the share in proximal-to-distal order."""

    punches: int
    contacts: int
    medians: dict[str, float | None]
    proximal_to_distal_share: float

    def to_json(self) -> dict[str, object]:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> NaturalnessSummary:
        """Back from `to_json` (other keys beside it are ignored)."""
        return cls(int(data["punches"]), int(data["contacts"]), dict(data["medians"]), float(data["proximal_to_distal_share"]))


def summarise(punches: list[PunchNaturalness]) -> NaturalnessSummary:
    """Medians over `punches` (time to contact over the punches that touched; None when none did)."""
    medians: dict[str, float | None] = {}
    for figure in FIGURES:
        values = [getattr(p, figure.key) for p in punches if getattr(p, figure.key) is not None]
        medians[figure.key] = float(np.median(values)) if values else None
    share = float(np.mean([p.proximal_to_distal for p in punches])) if punches else 0.0
    return NaturalnessSummary(len(punches), sum(p.time_to_contact_s is not None for p in punches), medians, share)


# --- the motion capture ---------------------------------------------------------------------------------------

def trunk_lean_deg(punch: CapturedPunch) -> np.ndarray:
    """Per frame: the angle of the line from the lower back to the neck from vertical (degrees)."""
    return np.asarray(np.degrees(angle_between(punch.joint("Neck") - punch.joint("LowerBack"), np.array([0.0, 1.0, 0.0]))), dtype=np.float64)


def capture_joint_speeds(punch: CapturedPunch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame (central differences, rad/s): the trunk's rotation about the vertical relative to the hips (the
    shoulder line's yaw less the hip line's), the right upper arm's angular speed relative to the trunk, and the
    right elbow's rate of opening."""
    dt = punch.frame_time_s

    def yaw(left: str, right: str) -> np.ndarray:
        line = punch.joint(left) - punch.joint(right)
        return np.unwrap(np.arctan2(line[:, 2], line[:, 0]))

    waist = np.gradient(yaw("LeftArm", "RightArm") - yaw("LeftUpLeg", "RightUpLeg"), dt)
    up = punch.joint("Neck") - punch.joint("LowerBack")
    across = punch.joint("LeftArm") - punch.joint("RightArm")
    across = across - (np.sum(across * up, axis=1) / np.sum(up * up, axis=1))[:, None] * up
    axes = [across / np.linalg.norm(across, axis=1, keepdims=True), up / np.linalg.norm(up, axis=1, keepdims=True)]
    axes.append(np.cross(axes[0], axes[1]))
    trunk = np.stack(axes, axis=1)  # [frames, 3 axes, 3]
    upper = punch.joint("RightForeArm") - punch.joint("RightArm")
    in_trunk = np.einsum("fij,fj->fi", trunk, upper / np.linalg.norm(upper, axis=1, keepdims=True))
    shoulder = np.linalg.norm(np.gradient(in_trunk, dt, axis=0), axis=1)
    elbow = np.gradient(angle_between(punch.joint("RightArm") - punch.joint("RightForeArm"),
                                       punch.joint("RightHand") - punch.joint("RightForeArm")), dt)
    return waist, shoulder, elbow


def captured_naturalness(punch: CapturedPunch) -> PunchNaturalness:
    """The figures of one captured punch: onset to full reach, the whole punch onset to `end`."""
    dt = punch.frame_time_s
    until = slice(punch.onset, punch.reach + 1)
    hand, off = punch.joint("RightHand"), punch.joint("LeftHand")
    hand_speed, off_speed = speeds_from_positions(hand, dt), speeds_from_positions(off, dt)
    waist, shoulder, elbow = capture_joint_speeds(punch)
    return PunchNaturalness(
        path_over_chord=path_over_chord(hand[until]),
        chord_distance_m=largest_distance_from_chord(hand[until]),
        off_fist_from_guard_m=largest_distance_from_start(off[until]),
        off_fist_from_guard_whole_m=largest_distance_from_start(off[punch.onset:]),
        off_fist_peak_speed_mps=float(off_speed[punch.onset:punch.reach].max()),
        off_fist_peak_speed_whole_mps=float(off_speed[punch.onset:].max()),
        trunk_flexion_deg=float(trunk_lean_deg(punch)[until].max()),
        trunk_flexion_whole_deg=float(trunk_lean_deg(punch)[punch.onset:].max()),
        fist_peak_speed_mps=float(hand_speed[punch.onset:punch.reach].max()),
        proximal_to_distal=in_proximal_to_distal_order(waist[until], shoulder[until], elbow[until]),
        time_to_contact_s=(punch.reach - punch.onset) * dt,
        elbow_bend_at_contact_deg=180.0 - float(np.degrees(angle_between(
            punch.joint("RightArm")[punch.reach] - punch.joint("RightForeArm")[punch.reach],
            punch.joint("RightHand")[punch.reach] - punch.joint("RightForeArm")[punch.reach]))),
    )


def capture_figures(path: Path = DEFAULT_BVH) -> list[PunchNaturalness] | None:
    """The figures of the four captured punches."""
    return [captured_naturalness(punch) for punch in captured_punches(path)]


# --- the table --------------------------------------------------------------------------------------------------

def _value(value: float | None, figure: Figure) -> str:
    return "-" if value is None else f"{value * figure.scale:.{figure.digits}f}{figure.unit}"


def naturalness_table(columns: list[tuple[str, NaturalnessSummary]], capture: list[PunchNaturalness] | None) -> list[str]:
    """A Markdown table: one row per figure, one column per summary (medians), and the captured punches' range."""
    header = ["figure (median)", *[title for title, _ in columns]] + (["captured punches (CMU 143/23, 4)"] if capture else [])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for figure in FIGURES:
        row = [figure.label, *[_value(summary.medians[figure.key], figure) for _, summary in columns]]
        if capture:
            values = [getattr(p, figure.key) for p in capture if getattr(p, figure.key) is not None]
            row.append(f"{_value(min(values), figure)} to {_value(max(values), figure)}" if values else "-")
        lines.append("| " + " | ".join(row) + " |")
    order = ["waist rotation, shoulder, elbow peak speeds in proximal-to-distal order",
             *[f"{100 * summary.proximal_to_distal_share:.0f}%" for _, summary in columns]]
    if capture:
        order.append(f"{sum(p.proximal_to_distal for p in capture)}/{len(capture)}")
    lines.append("| " + " | ".join(order) + " |")
    lines.append("| punches (touched the bag) | " + " | ".join(f"{s.punches} ({s.contacts})" for _, s in columns)
                 + (" | 4 |" if capture else " |"))
    return lines
