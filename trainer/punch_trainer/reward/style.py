"""Motion style: a prior, added by the product to any reward, that keeps a punch looking like a person's
(docs/style.md). The user still writes only their reward; the style decides how a punch may earn it.

A style has two parts, chosen by measurement (experiments/notebook.md, "A motion style"):

1. **A discount on what a punch earns.** Every frame has a style cost (fist speeds measured on the body, less
   the root's own walking and turning): the off (left) fist's distance from its guard and its speed, the waist's forward flexion, the punching fist's speed and, until it lands, its
   speed away from the target (a wind-up: captured punches go straight at it), each counted only
   beyond a free range that captured punches stay within (punch_trainer/data, CMU 143/23: the other hand moves
   12-20 cm at 1.2-1.8 m/s, the trunk leans 7-17 degrees, the fist peaks at 6.3-8.4 m/s), and growing with the
   square of the excess. A frame's positive reward is multiplied by exp(-weight x the cost so far), and a
   tenth of every later frame's cost is taken from it too (so flailing after the fist lands is not free): a
   punch that flails earns less, but any hit still earns more than standing still. Penalties added to the
   reward instead made the search settle on standing still, since every exploratory motion then scores below
   zero (experiments/notebook.md, "A motion style"); subtracting even 2% of the cost as well made the punching
   arm wind up and missed a far target.
   The order styles add a charge that takes the whole punch's earnings, for a punch whose waist, shoulder and
   elbow do not peak in the proximal-to-distal order (`whole_punch_cost`; docs/style.md, "The proximal-to-distal
   order").
2. **A narrower search around the guard** for the degrees of freedom that a punch moves least: the trajectory
   search's sigma for the waist's flexion and the off arm starts small and never grows past it, so the
   search explores the punching arm and the trunk's turn, not the guard hand.

`--style none` applies neither, and every command then does what it did before styles existed.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from punch_trainer.errors import PunchError
from punch_trainer.scene import SCENE_ARM_LENGTHS_M, SCENE_BAG_RADIUS_M

CONTACT_IMPULSE_NS = 1e-3
"""A right-fist impulse on the bag above this (N s) counts as contact."""

FramesLike = Callable[[str], np.ndarray]
"""`frames[name]` of punch_trainer.reward.rewards.Frames: a feature's values [..., frames]"""



class StyleError(PunchError):
    """A style name or weight that the trainer does not know or cannot use."""


@dataclass(frozen=True)
class Style:
    """What a human-looking punch stays within, and what straying beyond costs. Distances in m, speeds in
    m/s, angles in rad; each cost coefficient is per frame and per unit of the squared excess."""

    name: str
    weight: float = 1.0
    """scales the whole style: 0 is no style, 1 the measured default"""
    off_fist_free_m: float = 0.08
    off_fist_cost_per_m2: float = 100.0
    off_fist_free_mps: float = 1.5
    off_fist_cost_per_mps2: float = 0.2
    waist_flexion_free_rad: float = float(np.radians(12.0))
    waist_flexion_cost_per_rad2: float = 20.0
    fist_free_mps: float = 9.0
    fist_cost_per_mps2: float = 0.2
    fist_back_free_mps: float = 0.5
    """the punching fist's speed away from the target before it lands (a wind-up, drawing the fist back)"""
    fist_back_cost_per_mps2: float = 0.5
    chain_cost: float = 0.0
    """cost of a joint turning faster, relative to a captured punch's peak, than the joint before it in the chain
    (waist rotation, shoulder, elbow) has turned so far, until the fist lands: the proximal-to-distal order of
    boxing (0 in `boxing`; tried as `boxing_chain`: experiments/notebook.md)"""
    drive_cost: float = 0.0
    """cost of the shoulder or the elbow turning slower, relative to a captured punch's peak, than it already has,
    until the fist lands: the arm drives into the target, so its joints peak at contact, with the waist, whose
    turn the policies already speed up until contact (tried as `boxing_drive`: experiments/notebook.md)"""
    chain_peak_rad_s: tuple[float, float, float] = (3.0, 10.0, 18.0)
    """waist rotation, shoulder and elbow speeds the chain measures against: the captured punches' peaks
    (punch_trainer/data, CMU 143/23, from joint positions: the shoulder line's yaw 3.5-5.4, the upper arm's direction
    12.6-18.8, the elbow angle 23.7-30.8 rad/s, peaking in that order in 3 of 4 punches) scaled so that the
    elbow's is what the motors reach (18 rad/s)"""
    landing_zone_m: float = 0.3
    """how near the bag (the fist's distance from its centre, the presets' near zone) a punch is landing"""
    landing_free_mps: float = 0.0
    """the punching fist's speed, on the body, below which a landing punch (inside the zone, before contact) costs"""
    landing_cost_per_mps2: float = 0.0
    """cost per charged frame of a landing punch (every landing frame, or its first with `landing_at_entry`), per
    (m/s)^2 by which the fist is slower than `landing_free_mps`"""
    landing_floor_with_arm: bool = False
    """the floor scales with the arm's length (upper arm and forearm, as sized) over the character scene's: the same
    joint speeds move a shorter arm's fist slower"""
    landing_reach_share: float = 0.0
    """the floor counts only where the bag's near side starts within this share of the arm's length (shoulder to
    fist centre, as sized) from the shoulder, across the ground; a farther target is left to a slower punch at
    full stretch (0: the floor counts everywhere)"""
    landing_at_entry: bool = False
    """the shortfall is charged once a punch, on its first landing frame (the fist's speed as it enters the zone),
    instead of on every landing frame: a slow punch that still lands, as one knocked off its line recovers, is
    charged no more than a fast one that lands after fewer frames"""
    landing_shortfall_cap_mps: float = float("inf")
    """the most of the shortfall that costs: a slow landing keeps part of what it earns"""
    waist_lead_cost: float = 0.0
    """cost of the waist's rotation speeding up (per (rad/s)^2 of the frame's gain) while a punch is landing: the
    trunk's turn peaks before the fist lands, as in boxing's proximal-to-distal order"""
    contact_not_before_frames: int = 0
    """the first frame a punch may touch the bag without `early_contact_cost_per_frame` (captured punches take 17-22
    frames at 120 Hz from onset to full reach; the policies touch the bag after 7-9)"""
    early_contact_cost_per_frame: float = 0.0
    """cost, charged on the first contact frame, per frame by which it comes before `contact_not_before_frames`"""
    order_cost_per_frame: float = 0.0
    """cost per frame by which the peaks of the waist's rotation, the shoulder's and the elbow's speeds until the
    first contact come out of the proximal-to-distal order (the waist's after the shoulder's, the shoulder's after
    the elbow's), as docs/naturalness.md measures it; unlike the other costs it takes the whole punch's earnings,
    those before it too, so a punch cannot land early to escape it (`whole_punch_cost`)"""
    order_margin_frames: int = 0
    """how many frames before the next joint's a joint's peak must come to escape the order's charge (0: a tie is in
    order, as the measure counts it; 1: a tie costs a frame, so that noise does not break a punch held at a tie)"""
    order_cost_cap: float = float("inf")
    """the most the order's charge takes in all (exp(-cap) of the punch's earnings stays), so that a punch that can
    reach the bag only out of order (a short arm's) still earns more by landing than by missing"""
    order_reach_share: float = 0.0
    """the order is charged only where the bag's near side starts within this share of the arm's length from the
    shoulder (`reach_share`, as `landing_reach_share`); a farther target, which a short arm reaches only at full
    stretch with the trunk's lean, is left to land out of order (0: the order counts everywhere)"""
    order_charged_at_contact: bool = False
    """the order's charge all at once on the first contact frame, so that a punch which never touches the bag
    escapes it (the first form, in the `boxing_order` styles before `boxing_ordered`: a policy trained with it
    stopped short of targets that its short arms reached only out of order, experiments/notebook.md)"""
    miss_after_frames: int = 0
    """the frame from which a punch that has not yet touched the bag is charged `miss_cost_per_frame` a frame"""
    miss_cost_per_frame: float = 0.0
    """cost, taking the whole punch's earnings as the order's does, of each frame from `miss_after_frames` on
    before the fist first touches the bag, so that with a reward that pays near the bag without a touch (the
    hook's, the swing's) stopping short is not a way out of the order's charge (0: none; tried on the hook: it did
    not keep short arms' hits, experiments/notebook.md)"""
    arm_first_cost: float = 0.0
    """cost, taking the whole punch's earnings as the order's does, on the first frame on which the character
    touches the bag elsewhere than with its punching fist (the forearm, the elbow, the other fist) before that
    fist has: a bag pushed by the forearm is no hit in a game (`punch eval`'s success, the controller's `hit`),
    and under noise the ordered straight's forearm met near bags first (0: none; experiments/notebook.md)"""
    arm_first_reach_share: float = 0.0
    """`arm_first_cost` only where the bag's near side starts within this share of the arm's length from the
    shoulder (`reach_share`, as `order_reach_share`): a short arm at a far bag leans in, and its trunk may meet the
    bag before its fist (0: everywhere)"""
    later_cost_share: float = 0.1
    """how much of the cost after a frame still discounts what that frame earned (0: only the cost before it;
    1: all of it, the whole punch's)"""
    search_sigma: tuple[float, ...] = (0.1, 1.0, 1.0, 1.0, 1.0, 1.0, 0.05, 0.05, 0.05, 0.05)
    """the trajectory search's largest sigma per degree of freedom, in action order (punch_core::character::DOFS:
    waist flexion, waist rotation, the right shoulder's three and elbow, the left shoulder's three and elbow)"""

    def cost(self, frames: FramesLike) -> np.ndarray:
        """Each frame's style cost, [..., frames] (0 while everything stays within its free range)."""
        def vector(stem: str) -> np.ndarray:
            return np.stack([frames(f"{stem}_x"), frames(f"{stem}_y"), frames(f"{stem}_z")], axis=-1)

        def on_body(side: str) -> np.ndarray:
            """A fist's velocity relative to its body (less the root's walk and turn carrying it there): the
            body's own motion is the game's, not the punch's."""
            carried = vector("root_vel") + np.cross(vector("root_spin"), vector(f"fist_{side}_pos"))
            return np.asarray(vector(f"fist_{side}_vel") - carried)

        off_fist = vector("fist_l_pos")
        off_from_guard_m = np.linalg.norm(off_fist - off_fist[..., :1, :], axis=-1)
        off_speed_mps = np.linalg.norm(on_body("l"), axis=-1)
        fist_velocity = on_body("r")
        fist_speed_mps = np.linalg.norm(fist_velocity, axis=-1)
        waist_flexion_rad = frames("angle_waist_flexion")
        to_bag = vector("bag_pos") - vector("fist_r_pos")
        to_bag_unit = to_bag / np.maximum(np.linalg.norm(to_bag, axis=-1, keepdims=True), 1e-6)
        touching = fist_touching(frames)
        before_contact = np.cumsum(touching, axis=-1) == 0
        fist_back_mps = np.where(before_contact, -np.sum(fist_velocity * to_bag_unit, axis=-1), 0.0)

        def beyond(value: np.ndarray, free: float) -> np.ndarray:
            return np.asarray(np.maximum(0.0, value - free) ** 2)

        chain: np.ndarray | float = 0.0
        drive: np.ndarray | float = 0.0
        if self.chain_cost > 0.0 or self.drive_cost > 0.0:
            relative = [speed / peak for speed, peak in zip(chain_speeds(frames), self.chain_peak_rad_s, strict=True)]
            so_far = [np.maximum.accumulate(r, axis=-1) for r in relative]
            # Chain: each joint may turn (relative to its captured peak) as fast as the one before it has so far.
            ahead = np.maximum(0.0, relative[1] - so_far[0]) ** 2 + np.maximum(0.0, relative[2] - so_far[1]) ** 2
            chain = self.chain_cost * np.where(before_contact, ahead, 0.0)
            # Drive: the shoulder and the elbow do not slow before the fist lands.
            slowing = (so_far[1] - relative[1]) ** 2 + (so_far[2] - relative[2]) ** 2
            drive = self.drive_cost * np.where(before_contact, slowing, 0.0)
        slow_landing: np.ndarray | float = 0.0
        waist_lead: np.ndarray | float = 0.0
        if self.landing_cost_per_mps2 > 0.0 or self.waist_lead_cost > 0.0:
            landing = (frames("fist_r_bag_distance") < self.landing_zone_m) & before_contact
            floor_mps: np.ndarray | float = self.landing_free_mps
            if self.landing_floor_with_arm:
                arm_m = frames("body_upper_arm_m") + frames("body_forearm_m")
                floor_mps = self.landing_free_mps * arm_m / (SCENE_ARM_LENGTHS_M[0] + SCENE_ARM_LENGTHS_M[1])
            if self.landing_reach_share > 0.0:
                floor_mps = np.where(reach_share(frames) <= self.landing_reach_share, floor_mps, 0.0)
            slow = np.minimum(np.maximum(0.0, floor_mps - fist_speed_mps), self.landing_shortfall_cap_mps) ** 2
            charged = first_frame(landing) if self.landing_at_entry else landing
            slow_landing = self.landing_cost_per_mps2 * np.where(charged, slow, 0.0)
            # The waist's turn may not speed up once the punch is landing: it has peaked before.
            waist_speed = np.abs(frames("speed_waist_rotation"))
            waist_gain = np.diff(waist_speed, axis=-1, prepend=waist_speed[..., :1])
            waist_lead = self.waist_lead_cost * np.where(landing, np.maximum(0.0, waist_gain) ** 2, 0.0)
        early_contact: np.ndarray | float = 0.0
        if self.early_contact_cost_per_frame > 0.0:
            frames_early = np.maximum(0, self.contact_not_before_frames - np.arange(touching.shape[-1]))
            early_contact = self.early_contact_cost_per_frame * np.where(first_frame(touching), frames_early, 0.0)
        cost = (chain + drive + slow_landing + waist_lead + early_contact
                + self.off_fist_cost_per_m2 * beyond(off_from_guard_m, self.off_fist_free_m)
                + self.off_fist_cost_per_mps2 * beyond(off_speed_mps, self.off_fist_free_mps)
                + self.waist_flexion_cost_per_rad2 * beyond(waist_flexion_rad, self.waist_flexion_free_rad)
                + self.fist_cost_per_mps2 * beyond(fist_speed_mps, self.fist_free_mps)
                + self.fist_back_cost_per_mps2 * beyond(fist_back_mps, self.fist_back_free_mps))
        return np.asarray(self.weight * cost, dtype=np.float64)

    def whole_punch_cost(self, frames: FramesLike) -> np.ndarray:
        """Each frame's cost that takes all that the punch has earned, before the frame as after, [..., frames]:
        the proximal-to-distal order's (0 without `order_cost_per_frame`), a late touch's (0 without
        `miss_cost_per_frame`) and a touch elsewhere before the fist's (0 without `arm_first_cost`). For the order,
        frame t is charged the change, since frame t - 1, of how far the peaks of the waist's rotation, the shoulder's and the elbow's speeds up to t break the order; the peaks
        stop at the first contact. So the charges of a punch add up to its order as docs/naturalness.md measures
        it at contact, and a punch that never touches the bag is charged its peaks over the whole episode."""
        touching = fist_touching(frames)
        if self.order_cost_per_frame <= 0.0 and self.miss_cost_per_frame <= 0.0 and self.arm_first_cost <= 0.0:
            return np.zeros(touching.shape, dtype=np.float64)  # every style but the order's
        until_contact = np.cumsum(touching, axis=-1) - touching == 0  # up to and with the first contact frame
        late = until_contact & ~touching & (np.arange(touching.shape[-1]) >= self.miss_after_frames)
        touch_cost = self.miss_cost_per_frame * late
        if self.arm_first_cost > 0.0:
            arm_first = first_frame(elsewhere_touching(frames) & until_contact & ~touching)
            if self.arm_first_reach_share > 0.0:
                arm_first = arm_first & (reach_share(frames) <= self.arm_first_reach_share)
            touch_cost = touch_cost + self.arm_first_cost * arm_first
        if self.order_cost_per_frame <= 0.0:
            return np.asarray(self.weight * touch_cost, dtype=np.float64)
        peaks = [running_peak_frame(np.where(until_contact, speed, -1.0)) for speed in chain_speeds(frames)]
        margin = self.order_margin_frames
        out_of_order = np.maximum(0, peaks[0] - peaks[1] + margin) + np.maximum(0, peaks[1] - peaks[2] + margin)
        order_cost = np.minimum(self.order_cost_per_frame * out_of_order, self.order_cost_cap)
        if self.order_reach_share > 0.0:
            order_cost = np.where(reach_share(frames) <= self.order_reach_share, order_cost, 0.0)
        change = np.diff(order_cost, axis=-1, prepend=0)
        if self.order_charged_at_contact:
            change = np.where(first_frame(touching), order_cost, 0)
        return np.asarray(self.weight * (change + touch_cost), dtype=np.float64)

    def apply(self, terms: Mapping[str, np.ndarray], frames: FramesLike) -> dict[str, np.ndarray]:
        """The reward's terms with the style. A frame's positive value is discounted by exp(-the cost up to it),
        and what it earned stays at risk after it: each later frame's cost takes `later_cost_share` of it as
        well, so flailing after the fist lands costs part of what the punch earned. Negative values are left as
        they are. Frame by frame (causal, so A2C can score decision by decision): what the frame earns, less
        what its cost takes of the earnings held before it. A term's return, sum over frames f of
        earned_f x exp(-C_f - share x (C_end - C_f)) plus its losses, never falls below its losses alone:
        a hit still beats standing still."""
        cost, whole = self.cost(frames), self.whole_punch_cost(frames)
        discount = np.exp(-np.cumsum(cost + whole, axis=-1))
        # what a frame's cost leaves of the earnings held before it
        kept = np.exp(-self.later_cost_share * cost - whole)
        styled = {}
        for name, values in terms.items():
            earned = np.maximum(values, 0.0) * discount
            held = np.zeros_like(earned[..., 0])
            value = np.empty_like(earned)
            for frame in range(earned.shape[-1]):
                value[..., frame] = earned[..., frame] - held * (1.0 - kept[..., frame])
                held = held * kept[..., frame] + earned[..., frame]
            styled[name] = value + np.minimum(values, 0.0)
        return styled

    def search_sigma_cap(self, action_size: int) -> np.ndarray:
        """The search's sigma cap per degree of freedom, [action_size]."""
        if len(self.search_sigma) != action_size:
            raise StyleError(f"style '{self.name}' gives {len(self.search_sigma)} search sigmas for {action_size} "
                             "degrees of freedom")
        return np.asarray(self.search_sigma, dtype=np.float64)

    def to_json(self) -> dict[str, object]:
        return asdict(self)


STYLES: dict[str, Style | None] = {"none": None, "boxing": Style("boxing")}
"""the product's styles: `boxing`, measured on captured punches (docs/style.md), and `none`, the paper's reward
alone. Every other style is data: a table of a style file (`load_style_file`), named `FILE.toml:NAME`. The styles
the shipped policies' recipes use are in recipes/styles.toml; the ones experiments tried, in experiments/styles.toml."""
STYLE_FILE_SUFFIX = ".toml"
DEFAULT_STYLE = "boxing"
"""`punch train`'s style"""
MAX_WEIGHT = 100.0


def first_frame(mask: np.ndarray) -> np.ndarray:
    """Only the first True frame of each episode of `mask` [..., frames]."""
    return np.asarray(mask & (np.cumsum(mask, axis=-1) == 1))


def fist_touching(frames: FramesLike) -> np.ndarray:
    """Whether the punching fist touches the bag in each frame, [..., frames] (as `rewards.first_right_contact`
    reads contact)."""
    return np.asarray(np.linalg.norm(contact_impulse(frames, "fist_r"), axis=-1) > CONTACT_IMPULSE_NS)


def elsewhere_touching(frames: FramesLike) -> np.ndarray:
    """Whether the character touches the bag elsewhere than with its punching fist in each frame, [..., frames]:
    the whole character's contact impulse less that fist's."""
    impulse = contact_impulse(frames, "character") - contact_impulse(frames, "fist_r")
    return np.asarray(np.linalg.norm(impulse, axis=-1) > CONTACT_IMPULSE_NS)


def contact_impulse(frames: FramesLike, body: str) -> np.ndarray:
    """The contact impulse on `body` (a feature prefix: `fist_r`, `character`) in each frame, N s [..., frames, 3]."""
    return np.stack([frames(f"{body}_impulse_{axis}") for axis in "xyz"], axis=-1)


def chain_speeds(frames: FramesLike) -> list[np.ndarray]:
    """The speeds of the proximal-to-distal chain, rad/s [..., frames] each: the waist's rotation, the right
    shoulder's (its three axes together) and the right elbow's extension, as docs/naturalness.md measures them."""
    shoulder = np.sqrt(sum(frames(f"speed_shoulder_r_{axis}") ** 2 for axis in ("flexion", "rotation", "abduction")))
    return [np.abs(frames("speed_waist_rotation")), np.asarray(shoulder), np.abs(frames("speed_elbow_r_extension"))]


def running_peak_frame(values: np.ndarray) -> np.ndarray:
    """For each frame of `values` [..., frames], the frame of the largest value so far (the first, on a tie)."""
    frame = np.arange(values.shape[-1])
    best_before = np.maximum.accumulate(values, axis=-1)
    best_before = np.concatenate([np.full_like(values[..., :1], -np.inf), best_before[..., :-1]], axis=-1)
    return np.asarray(np.maximum.accumulate(np.where(values > best_before, frame, 0), axis=-1))


def reach_share(frames: FramesLike) -> np.ndarray:
    """How far the bag's near side is from the right shoulder at the episode's start, across the ground (the bag
    hangs upright, so a fist meets it at any height it reaches), as a share of the arm (shoulder to fist centre):
    [..., 1], under 1 where the fist reaches it without the trunk. The shoulder sits at the character's rest
    place (the scene's: its shoulders' midpoint over the root, half the shoulder width to the right)."""
    bag_side_m = frames("bag_pos_x")[..., :1] + 0.5 * frames("body_shoulder_width_m")[..., :1]
    near_side_m = np.hypot(bag_side_m, frames("bag_pos_z")[..., :1]) - SCENE_BAG_RADIUS_M
    return np.asarray(near_side_m / (frames("body_upper_arm_m") + frames("body_forearm_m"))[..., :1])


def style_named(name: str, weight: float = 1.0) -> Style | None:
    """The style `name` at `weight`: `none` (None, as is a weight of 0), `boxing`, or `FILE.toml:NAME`, the table
    NAME of a style file."""
    if not np.isfinite(weight) or not 0.0 <= weight <= MAX_WEIGHT:
        raise StyleError(f"style weight {weight} must be a number from 0 to {MAX_WEIGHT:g}")
    file, separator, table = name.rpartition(":")
    if separator and file.endswith(STYLE_FILE_SUFFIX):
        in_file = load_style_file(Path(file))
        if table not in in_file:
            raise StyleError(f"{file} has no style '{table}' (it has {', '.join(in_file) or 'none'})")
        style: Style | None = in_file[table]
    elif name in STYLES:
        style = STYLES[name]
    else:
        raise StyleError(f"unknown style '{name}': use {', '.join(STYLES)}, or FILE.toml:NAME for a style of a file "
                         "(recipes/styles.toml, experiments/styles.toml)")
    if style is None or weight == 0.0:
        return None
    return replace(style, weight=float(weight))


def load_style_file(path: Path) -> dict[str, Style]:
    """The styles of a style file: one TOML table a style, its keys `Style`'s fields (lists for the tuples), and
    `base`, the name of an earlier table of the file (or `boxing`) whose values it changes."""
    try:
        tables = tomllib.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
        raise StyleError(f"{path}: not a readable style file ({error})") from None
    known = {field.name for field in fields(Style)}
    styles: dict[str, Style] = {}
    for name, table in tables.items():
        if not isinstance(table, dict):
            raise StyleError(f"{path}: '{name}' is not a table of a style's values")
        values = dict(table)
        base_name = values.pop("base", "boxing")
        base = styles.get(base_name) if base_name != "boxing" else STYLES["boxing"]
        if base is None:
            raise StyleError(f"{path}: style '{name}' changes '{base_name}', which is no earlier style of the file")
        unknown = sorted(set(values) - set(known) | ({"name", "weight"} & set(values)))
        if unknown:
            raise StyleError(f"{path}: style '{name}' sets {', '.join(unknown)}, which a style file cannot set "
                             f"(its values: {', '.join(sorted(set(known) - {'name', 'weight'}))})")
        try:
            changed: dict[str, Any] = {key: tuple(float(v) for v in value) if isinstance(value, list) else type(getattr(base, key))(value)
                       for key, value in values.items()}
        except (TypeError, ValueError) as error:
            raise StyleError(f"{path}: style '{name}': a value of the wrong kind ({error})") from None
        styles[name] = replace(base, name=name, **changed)
    return styles


def style_label(style: Style | None) -> str:
    """How runs, reports and policy metadata name a style: `none` or `NAME@WEIGHT`."""
    return "none" if style is None else f"{style.name}@{style.weight:g}"


def style_from_label(label: str) -> Style | None:
    """The inverse of `style_label`."""
    name, _, weight = label.partition("@")
    try:
        return style_named(name, float(weight) if weight else 1.0)
    except ValueError:
        raise StyleError(f"style '{label}': its weight is not a number") from None
