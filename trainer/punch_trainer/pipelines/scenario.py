"""Evaluation scenarios: what `punch eval` measures, as data. A scenario is a TOML file (the shipped ones in
punch_trainer/scenarios/, or any file): held-out placements drawn from a reach volume, and a list of conditions,
each a way to play a punch there (the noise, how the body and the target move, the arms' size, where the punch
starts), measured at each of its sigmas, one report row each. The format, key by key: docs/evaluation.md. Every
key is checked here before Godot starts, and an unknown one is refused, so a new kind of condition is a new key
(`CONDITION_KEYS`, `Condition`, then evaluate.gd's `_add_episode`), not a new harness. The evaluator
(`pipelines/evaluation.py`) turns a scenario into episodes for the one Godot driver and their results into rows.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Literal

import numpy as np

from punch_trainer.errors import PunchError
from punch_trainer.sim.conditions import ARM_SCALE_RANGE, SCENE_ARM_LENGTHS_M, SEGMENT_SCALE_RANGE, arm_scale

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
"""the shipped scenarios, `punch eval --scenario NAME` (package data)"""
SEED_STRIDE = (1_000_003, 100_003)
"""noise seed of episode e at sigma index s of a condition: noise_seed * 1000003 + s * 100003 + e"""


class ScenarioError(PunchError):
    """A scenario cannot be evaluated: no such scenario, a key it does not know, or a value out of its range."""


@dataclass(frozen=True)
class Motion:
    """How a node moves from the episode's start (a body) or the punch's (a target's hook), in its own frame at
    the start (evaluate.gd plays it as a game moves a CharacterBody3D)."""

    velocity_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """[left, up, forward]"""
    turn_dps: float = 0.0
    """about the vertical through the character's root, positive to the left"""
    lunge_m: float = 0.0
    """forward over `lunge_s`, minimum-jerk, with the punch"""
    lunge_s: float = 0.25
    bob_m: float = 0.0
    """vertical amplitude of a sine at `bob_hz`"""
    bob_hz: float = 2.0

    def to_wire(self) -> dict[str, Any]:
        return {**asdict(self), "velocity_mps": list(self.velocity_mps)}


STRUCK_PARTS = ("head", "torso", "left_arm", "right_arm")
STRUCK_FROM = {"front": (0.0, 0.0, -1.0), "back": (0.0, 0.0, 1.0), "left": (-1.0, 0.0, 0.0), "right": (1.0, 0.0, 0.0)}
"""where a hit comes from, and the way it pushes the character (its own frame: +Z ahead, +X its left)"""


@dataclass(frozen=True)
class Struck:
    """A hit the game lands on the standing character (`PunchCharacter.take_hit`) instead of a punch: the episode
    measures the body's reaction and its way back to guard (`recovered`; after a knock-down, `recover()` 1 s on)."""

    impulse_ns: float
    part: str = "torso"
    """one of STRUCK_PARTS"""
    from_side: str = "front"
    """one of STRUCK_FROM: the push's direction, turned about the vertical by up to `spread_deg` either way per episode"""
    spread_deg: float = 15.0

    def direction(self, rng: np.random.Generator) -> list[float]:
        """The push's unit direction in the character's frame, turned by a random yaw within the spread."""
        x, y, z = STRUCK_FROM[self.from_side]
        yaw = np.radians(rng.uniform(-self.spread_deg, self.spread_deg))
        return [round(float(x * np.cos(yaw) + z * np.sin(yaw)), 6), y, round(float(-x * np.sin(yaw) + z * np.cos(yaw)), 6)]


@dataclass(frozen=True)
class Defender:
    """A second character of the addon's scene standing in the bag's place, facing the puncher: its root at the
    placement's distance and side, and the punch aimed at its head (its `Head` body) or its torso. The rows count what
    the punch became (`punch_finished`'s outcome) and how often, and how hard, the fist reached the part aimed at."""

    blocks: bool = False
    """its controller calls `block()` as the episode starts; the punch comes `lead_s` later (the warning)"""
    part: Literal["head", "torso"] = "head"
    """the body the punch aims at: the head, or the torso (a body shot)"""
    head_up_m: float = 0.0
    """its head moved this far up its neck (`PunchCharacter.size_head`), as an own rig's head sits: its block's high
    guard rises with it"""
    turned_deg: float = 0.0
    """its body (the pelvis, the game's) turned this far to its left (negative: its right) from facing the puncher,
    as a game's fighter caught off line: its block turns the trunk back toward its target (the puncher)"""
    motion: Motion | None = None
    """how it moves (its root, as a game moves its CharacterBody3D), in its own frame at the start (+X its left, +Z
    toward the puncher), from the episode's start (with the block) or, with no lead, the punch's"""


@dataclass(frozen=True)
class Condition:
    """One way to play a punch at every placement; a report row at each of its sigmas."""

    name: str
    sigmas: tuple[float, ...]
    noise_seed: int
    noise_decisions: int = -1
    start: Literal["guard", "after_punch"] = "guard"
    arms: tuple[float, float] = (1.0, 1.0)
    lead_s: float = 0.0
    body: Motion | None = None
    target: Motion | None = None
    swinging: bool = False
    """the bag swinging at the start (the placements' swinging twins)"""
    move: str = ""
    """the move thrown (`punch(&"jab")`, the policy as the moveset's for it; a left-hand move at the mirror image of each
    placement); empty: the policy with the right hand"""
    stance: Literal["orthodox", "southpaw"] = "orthodox"
    """the controller's stance, which says the move's hand"""
    stance_pose: bool = False
    """the character stands in the stance's guard (`PunchController.stance_pose`) and punches from there"""
    combo: tuple[str, ...] = ()
    """moves thrown as one `combo()` with the addon's moveset (every move's shipped policy), at the placement as drawn
    for both hands; a punch succeeds when every one of them struck the target"""
    until_recovered: bool = False
    """the character returns to guard after its (last) punch and the episode waits for it (the frame data's
    recovery)"""
    guard_first: bool = True
    """`PunchController.guard_first`: a punch asked for away from the guard returns there first; false: it starts
    from wherever the arms are"""
    reset_target: bool = False
    """each later punch of a combo starts with the bag hanging as placed again, not where the punches before swung
    it (what a punch from another's recovery can reach, whatever the target did)"""
    struck: Struck | None = None
    """a hit on the standing character instead of a punch (its rows: how far the body turned, when it was back)"""
    defender: Defender | None = None
    """a defending character instead of the bag, the punch at its head (success: the punch was blocked)"""
    cancel_delay_s: tuple[float, float] = (0.0, 0.0)
    """a combo's cancel windows: each episode draws one delay (s, uniform in this band, from its seed) for every
    move of the moveset, so the next punch starts at a random moment after the one before landed"""

    def moves(self) -> bool:
        return self.body is not None or self.target is not None or (self.defender is not None and self.defender.motion is not None)


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    source: str
    """the file it was read from"""
    success: Literal["hit", "return"]
    placements: int
    seed: int
    volume: Literal["policy", "spec"]
    conditions: tuple[Condition, ...]
    distance_m: tuple[float, float] | None = None
    """a band of target distances that replaces the volume's (a defender's root, out of reach of the puncher's guard);
    None: the volume's"""
    height_m: tuple[float, float] | None = None
    """a band of target heights that replaces the volume's (a body band below the head band); None: the volume's"""
    side_m: tuple[float, float] | None = None
    """a band of target sides that replaces the volume's (a combo's target, in front of both hands); None: the volume's"""
    noisy_punches: int = 1
    search_iterations: int = 0
    naturalness: bool = False

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


CONDITION_KEYS = ("name", "sigmas", "noise_decisions", "noise_seed", "start", "arms", "lead_s", "body", "target", "move",
                  "stance", "stance_pose", "combo", "until_recovered", "guard_first", "reset_target",
                  "cancel_delay_s", "struck", "defender")
COMBO_MOVES = ("jab", "cross", "lead_hook", "rear_hook", "lead_uppercut", "rear_uppercut")
LEAD_MOVES = ("jab", "lead_hook", "lead_uppercut")
"""the moves of the lead hand (the left in the orthodox stance; punch_core::game::moves)"""
SCENARIO_KEYS = ("name", "description", "success", "placements", "noisy_punches", "search_iterations", "naturalness",
                 "conditions")
PLACEMENT_KEYS = ("count", "seed", "volume", "distance_m", "height_m", "side_m")
MOTION_KEYS = tuple(field.name for field in fields(Motion))


def shipped_scenarios() -> list[str]:
    return sorted(path.stem for path in SCENARIO_DIR.glob("*.toml"))


def scenario_path(name_or_file: str | Path) -> Path:
    """A shipped scenario's file by its name, or the file named."""
    text = str(name_or_file)
    if text.endswith(".toml") or "/" in text:
        path = Path(text)
        if not path.is_file():
            raise ScenarioError(f"scenario file not found: {path}")
        return path
    path = SCENARIO_DIR / f"{text}.toml"
    if not path.is_file():
        raise ScenarioError(f"no scenario named '{text}'; the shipped ones are {', '.join(shipped_scenarios())} (or name a .toml file)")
    return path


def read_scenario_data(name_or_file: str | Path) -> tuple[dict[str, Any], str]:
    """A scenario's raw data (to override before `build_scenario`) and the file it came from."""
    path = scenario_path(name_or_file)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as error:
        raise ScenarioError(f"{path}: not TOML ({error})") from None
    shipped = path.resolve().is_relative_to(SCENARIO_DIR.resolve())
    # A shipped scenario is named by its place in the repository, the same on every machine.
    return data, str(path.resolve().relative_to(SCENARIO_DIR.resolve().parents[2])) if shipped else str(path)


def load_scenario(name_or_file: str | Path) -> Scenario:
    data, source = read_scenario_data(name_or_file)
    return build_scenario(data, source)


def _number(where: str, value: Any, low: float | None = None, high: float | None = None, whole: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (whole and not isinstance(value, int)):
        raise ScenarioError(f"{where} {value!r}: must be {'a whole number' if whole else 'a number'}")
    if not math.isfinite(value) or (low is not None and value < low) or (high is not None and value > high):
        bounds = " and ".join(part for part in (f"at least {low:g}" if low is not None else "",
                                                 f"at most {high:g}" if high is not None else "") if part)
        raise ScenarioError(f"{where} {value!r}: must be a finite number{', ' + bounds if bounds else ''}")
    return value


def _unknown(where: str, table: Mapping[str, Any], known: Sequence[str]) -> None:
    unknown = [key for key in table if key not in known]
    if unknown:
        raise ScenarioError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; known: {', '.join(known)}")


def check_arms(upper: float, forearm: float, where: str = "arms") -> tuple[float, float]:
    """The arms as given; ScenarioError when PunchCharacter.size_arms would refuse them (each length, or the
    arm's), naming what it accepts."""
    arm = arm_scale(upper, forearm)
    segments_ok = all(SEGMENT_SCALE_RANGE[0] <= v <= SEGMENT_SCALE_RANGE[1] for v in (upper, forearm))
    if not (segments_ok and ARM_SCALE_RANGE[0] <= arm <= ARM_SCALE_RANGE[1]):
        if upper == forearm or (math.isnan(upper) and math.isnan(forearm)):
            raise ScenarioError(f"arm scale {upper:g} is outside the range PunchCharacter.size_arms accepts: "
                                f"{ARM_SCALE_RANGE[0]:g} to {ARM_SCALE_RANGE[1]:g} times the character scene's arm "
                                f"(shoulder to fist centre {sum(SCENE_ARM_LENGTHS_M[:2]):.3f} m)")
        raise ScenarioError(f"{where} {upper:g}x{forearm:g} are outside what PunchCharacter.size_arms accepts: each "
                            f"length {SEGMENT_SCALE_RANGE[0]:g} to {SEGMENT_SCALE_RANGE[1]:g} times the scene's, the arm "
                            f"{ARM_SCALE_RANGE[0]:g} to {ARM_SCALE_RANGE[1]:g} times (these make it {arm:.3f})")
    return upper, forearm


def size_label(upper: float, forearm: float) -> str:
    """`0.75` for both lengths times 0.75, `0.7x0.85` for other proportions."""
    return f"{upper:g}" if upper == forearm else f"{upper:g}x{forearm:g}"


def _arms(where: str, value: Any) -> tuple[float, float]:
    if isinstance(value, (list, tuple)) and len(value) == 2:
        upper, forearm = (float(_number(where, v)) for v in value)
    elif isinstance(value, (list, tuple)) and len(value) == 1:
        upper = forearm = float(_number(where, value[0]))
    else:
        upper = forearm = float(_number(where, value))
    return check_arms(upper, forearm, where)


def _motion(where: str, value: Any) -> Motion:
    if not isinstance(value, Mapping):
        raise ScenarioError(f"{where}: a motion is a table ({', '.join(MOTION_KEYS)})")
    _unknown(where, value, MOTION_KEYS)
    velocity = value.get("velocity_mps", [0.0, 0.0, 0.0])
    if not isinstance(velocity, list) or len(velocity) != 3:
        raise ScenarioError(f"{where}.velocity_mps: three numbers, [left, up, forward] (m/s)")
    scalars = {key: float(_number(f"{where}.{key}", value[key], 0.0 if key in ("lunge_s", "bob_hz", "bob_m") else None))
               for key in MOTION_KEYS if key != "velocity_mps" and key in value}
    if scalars.get("lunge_s", 0.25) <= 0:
        raise ScenarioError(f"{where}.lunge_s: must be more than 0")
    return Motion(velocity_mps=(float(_number(where, velocity[0])), float(_number(where, velocity[1])),
                                float(_number(where, velocity[2]))), **scalars)


def _sigmas(where: str, value: Any, scenario_sigmas: list[float]) -> tuple[float, ...]:
    if value == "noisy":
        return tuple(s for s in scenario_sigmas if s > 0)
    if value == "all":
        return tuple(scenario_sigmas)
    if not isinstance(value, list):
        raise ScenarioError(f"{where}: a list of sigmas, \"all\" (the scenario's) or \"noisy\" (the scenario's above 0)")
    return tuple(float(_number(where, sigma, 0.0, 1.0)) for sigma in value)


def _condition(index: int, table: Any, defaults: Mapping[str, Any], scenario_sigmas: list[float], seed: int) -> Condition:
    where = f"condition {index + 1}"
    if not isinstance(table, Mapping):
        raise ScenarioError(f"{where}: a table ([[conditions]])")
    _unknown(where, table, CONDITION_KEYS)
    merged = {**defaults, **table}
    name = merged.get("name")
    if not isinstance(name, str) or not name:
        raise ScenarioError(f"{where}: needs a name")
    where = f"condition '{name}'"
    start = merged.get("start", "guard")
    if start not in ("guard", "after_punch"):
        raise ScenarioError(f"{where}: start is \"guard\" or \"after_punch\", not {start!r}")
    body = _motion(f"{where}: body", merged["body"]) if "body" in merged else None
    target_table = merged.get("target")
    swinging, target = False, None
    if target_table is not None:
        if not isinstance(target_table, Mapping):
            raise ScenarioError(f"{where}: target is a motion table or {{ swinging = true }}")
        swinging = bool(target_table.get("swinging", False))
        rest = {k: v for k, v in target_table.items() if k != "swinging"}
        if swinging and rest:
            raise ScenarioError(f"{where}: a swinging target is not moved by its hook too")
        target = None if swinging else _motion(f"{where}: target", rest)
    if body is not None and target is not None:
        raise ScenarioError(f"{where}: moves both the body and the target's hook; one of them at a time")
    noise_seed = merged.get("noise_seed", seed)
    move, stance = merged.get("move", ""), merged.get("stance", "orthodox")
    if not isinstance(move, str):
        raise ScenarioError(f"{where}: move is a move's name (\"jab\", \"cross\", ...), not {move!r}")
    if stance not in ("orthodox", "southpaw"):
        raise ScenarioError(f"{where}: stance is \"orthodox\" or \"southpaw\", not {stance!r}")
    stance_pose = merged.get("stance_pose", False)
    if not isinstance(stance_pose, bool):
        raise ScenarioError(f"{where}: stance_pose is true or false, not {stance_pose!r}")
    until_recovered = merged.get("until_recovered", False)
    if not isinstance(until_recovered, bool):
        raise ScenarioError(f"{where}: until_recovered is true or false, not {until_recovered!r}")
    combo = merged.get("combo", [])
    if not isinstance(combo, list) or any(m not in COMBO_MOVES for m in combo):
        raise ScenarioError(f"{where}: combo is a list of moves ({', '.join(COMBO_MOVES)}), not {combo!r}")
    if combo and move:
        raise ScenarioError(f"{where}: a move or a combo, not both")
    if combo and start != "guard":
        raise ScenarioError(f"{where}: a combo starts from guard")
    guard_first = merged.get("guard_first", True)
    if not isinstance(guard_first, bool):
        raise ScenarioError(f"{where}: guard_first is true or false, not {guard_first!r}")
    cancel_delay_s = _delay_band(f"{where}: cancel_delay_s", merged.get("cancel_delay_s", [0.0, 0.0]))
    if cancel_delay_s != (0.0, 0.0) and not combo:
        raise ScenarioError(f"{where}: cancel_delay_s delays a combo's next punch; it needs a combo")
    reset_target = merged.get("reset_target", False)
    if not isinstance(reset_target, bool) or (reset_target and not combo):
        raise ScenarioError(f"{where}: reset_target is true or false, and true only with a combo, not {reset_target!r}")
    struck = _struck(f"{where}: struck", merged["struck"]) if "struck" in merged else None
    if struck is not None and (combo or move or start != "guard" or target is not None):
        raise ScenarioError(f"{where}: a struck character holds its guard (standing, or on a body motion): no move, "
                            "combo, start or target")
    defender = _defender(f"{where}: defender", merged["defender"]) if "defender" in merged else None
    if defender is not None and (combo or struck or start != "guard" or body is not None or target is not None):
        raise ScenarioError(f"{where}: a defender stands in the bag's place for one punch from guard: no combo, struck, "
                            "start, body or target")
    return Condition(
        name=name, sigmas=_sigmas(f"{where}: sigmas", merged.get("sigmas", "all"), scenario_sigmas),
        noise_seed=int(_number(f"{where}: noise_seed", noise_seed, 0, 2**32 - 1, whole=True)),
        noise_decisions=int(_number(f"{where}: noise_decisions", merged.get("noise_decisions", -1), -1, 10_000, whole=True)),
        start=start, arms=_arms(f"{where}: arms", merged.get("arms", 1.0)),
        lead_s=float(_number(f"{where}: lead_s", merged.get("lead_s", 0.0), 0.0, 10.0)),
        body=body, target=target, swinging=swinging, move=move, stance=stance, stance_pose=stance_pose,
        combo=tuple(combo), until_recovered=until_recovered, guard_first=guard_first,
        reset_target=reset_target, cancel_delay_s=cancel_delay_s, struck=struck, defender=defender)


def _defender(where: str, table: Any) -> Defender:
    """A `defender = { blocks = true, part = "torso", head_up_m = 0.06, turned_deg = 30, motion = {...} }` table,
    checked."""
    if not isinstance(table, Mapping):
        raise ScenarioError(f"{where}: a table ({{ blocks = true }})")
    _unknown(where, table, ("blocks", "part", "head_up_m", "turned_deg", "motion"))
    blocks = table.get("blocks", False)
    if not isinstance(blocks, bool):
        raise ScenarioError(f"{where}.blocks: true or false, not {blocks!r}")
    part = table.get("part", "head")
    if part not in ("head", "torso"):
        raise ScenarioError(f"{where}.part: \"head\" or \"torso\", not {part!r}")
    # Checked here so that a scenario file fails before Godot starts: inside what `size_head` accepts for the addon's
    # head (`HEAD_CROWN_SCALE_RANGE`, punch_core/src/contract/head_size.rs); the engine refuses anything beyond that.
    head_up_m = table.get("head_up_m", 0.0)
    if isinstance(head_up_m, bool) or not isinstance(head_up_m, int | float) or not -0.04 <= head_up_m <= 0.11:
        raise ScenarioError(f"{where}.head_up_m: metres from -0.04 to 0.11 (what `size_head` accepts), not {head_up_m!r}")
    turned_deg = table.get("turned_deg", 0.0)
    if isinstance(turned_deg, bool) or not isinstance(turned_deg, int | float) or not -90.0 <= turned_deg <= 90.0:
        raise ScenarioError(f"{where}.turned_deg: degrees from -90 to 90, not {turned_deg!r}")
    motion = _motion(f"{where}.motion", table["motion"]) if "motion" in table else None
    return Defender(blocks=blocks, part=part, head_up_m=float(head_up_m), turned_deg=float(turned_deg), motion=motion)


def _struck(where: str, table: Any) -> Struck:
    """A `struck = { impulse_ns = 30, part = "head", from = "right", spread_deg = 15 }` table, checked."""
    if not isinstance(table, Mapping):
        raise ScenarioError(f"{where}: a table {{ impulse_ns = ..., part = ..., from = ... }}")
    _unknown(where, table, ("impulse_ns", "part", "from", "spread_deg"))
    if "impulse_ns" not in table:
        raise ScenarioError(f"{where}: needs impulse_ns")
    part, side = table.get("part", "torso"), table.get("from", "front")
    if part not in STRUCK_PARTS:
        raise ScenarioError(f"{where}: part is one of {', '.join(STRUCK_PARTS)}, not {part!r}")
    if side not in STRUCK_FROM:
        raise ScenarioError(f"{where}: from is one of {', '.join(STRUCK_FROM)}, not {side!r}")
    return Struck(impulse_ns=float(_number(f"{where}: impulse_ns", table["impulse_ns"], 0.0, 1000.0)), part=part, from_side=side,
                  spread_deg=float(_number(f"{where}: spread_deg", table.get("spread_deg", 15.0), 0.0, 90.0)))


def _delay_band(where: str, value: Any) -> tuple[float, float]:
    """A [low, high] band of delays in seconds (0-2 s), low first."""
    if not isinstance(value, list) or len(value) != 2:
        raise ScenarioError(f"{where}: a [low, high] band in seconds, not {value!r}")
    low, high = (float(_number(where, v, 0.0, 2.0)) for v in value)
    if low > high:
        raise ScenarioError(f"{where}: the lower delay first, not {value!r}")
    return low, high


def _band(source: str, placements: Mapping[str, Any], key: str, lowest: float, highest: float) -> tuple[float, float] | None:
    """placements.`key`, a [low, high] band in metres that replaces the volume's, checked; None when not given."""
    if key not in placements:
        return None
    band = placements[key]
    if not isinstance(band, list) or len(band) != 2:
        raise ScenarioError(f"{source}: placements.{key} is [low, high] in metres")
    low, high = (float(_number(f"placements.{key}", value, lowest, highest)) for value in band)
    if low > high:
        raise ScenarioError(f"{source}: placements.{key} [{low:g}, {high:g}] runs downward")
    return low, high


def build_scenario(data: Mapping[str, Any], source: str) -> Scenario:
    """The scenario of raw data (a file's, overridden by the command line), every key checked."""
    defaults = {key: value for key, value in data.items() if key in CONDITION_KEYS and key != "name"}
    _unknown(source, {k: v for k, v in data.items() if k not in defaults}, SCENARIO_KEYS)
    placements = data.get("placements", {})
    if not isinstance(placements, Mapping):
        raise ScenarioError(f"{source}: [placements] is a table ({', '.join(PLACEMENT_KEYS)})")
    _unknown(f"{source}: placements", placements, PLACEMENT_KEYS)
    count = int(_number("placements.count", placements.get("count", 32), 1, 10_000, whole=True))
    seed = int(_number("placements.seed", placements.get("seed", 0), 0, 2**32 - 1, whole=True))
    volume = placements.get("volume", "policy")
    if volume not in ("policy", "spec"):
        raise ScenarioError(f"{source}: placements.volume is \"policy\" or \"spec\", not {volume!r}")
    distance_m, height_m, side_m = (_band(source, placements, key, low, high) for key, low, high in (
        ("distance_m", 0.0, 3.0), ("height_m", 0.0, 3.0), ("side_m", -1.0, 1.0)))
    success = data.get("success", "hit")
    if success not in ("hit", "return"):
        raise ScenarioError(f"{source}: success is \"hit\" or \"return\", not {success!r}")
    raw_sigmas = defaults.get("sigmas", [0.0])
    if not isinstance(raw_sigmas, list):
        raise ScenarioError(f"{source}: sigmas is a list of numbers")
    scenario_sigmas = [float(_number("sigmas", s, 0.0, 1.0)) for s in raw_sigmas]
    defaults["sigmas"] = "all"
    tables = data.get("conditions", [])
    if not isinstance(tables, list) or not tables:
        raise ScenarioError(f"{source}: no [[conditions]]")
    conditions = [_condition(i, table, defaults, scenario_sigmas, seed) for i, table in enumerate(tables)]
    if success == "return" and any(c.combo or c.struck or c.defender for c in conditions):
        raise ScenarioError(f"{source}: a combo's, a struck character's or a defender's success is \"hit\" (a reward "
                            "scores one punch at a bag)")
    rows = [(c.name, sigma) for c in conditions for sigma in c.sigmas]
    doubled = sorted({row for row in rows if rows.count(row) > 1})
    if doubled:
        raise ScenarioError(f"{source}: two conditions named '{doubled[0][0]}' at sigma {doubled[0][1]:g}")
    conditions = [c for c in conditions if c.sigmas]
    if not conditions:
        raise ScenarioError(f"{source}: no condition has a sigma to play (sigmas {scenario_sigmas})")
    name = data.get("name", Path(source).stem)
    naturalness = data.get("naturalness", False)
    if not isinstance(naturalness, bool):
        raise ScenarioError(f"{source}: naturalness is true or false")
    return Scenario(name=str(name), description=str(data.get("description", "")), source=source, success=success,
                    placements=count, seed=seed, volume=volume, conditions=tuple(conditions), distance_m=distance_m,
                    height_m=height_m, side_m=side_m,
                    noisy_punches=int(_number("noisy_punches", data.get("noisy_punches", 1), 1, 1000, whole=True)),
                    search_iterations=int(_number("search_iterations", data.get("search_iterations", 0), 0, 100_000, whole=True)),
                    naturalness=naturalness)


def override(data: Mapping[str, Any], *, placements: int | None = None, seed: int | None = None,
             sigmas: list[float] | None = None, noisy_punches: int | None = None, search_iterations: int | None = None,
             lead_s: float | None = None, arms: tuple[float, float] | None = None, conditions: list[str] | None = None,
             scales: list[float] | None = None, proportions: list[tuple[float, float]] | None = None) -> dict[str, Any]:
    """A scenario's raw data with the command line's values over the file's (None: the file's). `conditions`: only
    those named; `scales` and `proportions`: the conditions of one arm size each (as the file's arm-size
    conditions are made: every other key the first of them has), scales for equal proportions first."""
    result = dict(data)
    table = dict(result.get("placements", {}))
    if placements is not None:
        table["count"] = placements
    if seed is not None:
        table["seed"] = seed
    result["placements"] = table
    for key, value in [("sigmas", sigmas), ("noisy_punches", noisy_punches), ("search_iterations", search_iterations),
                       ("lead_s", lead_s), ("arms", list(arms) if arms is not None else None)]:
        if value is not None:
            result[key] = value
    tables = [dict(t) for t in result.get("conditions", []) if isinstance(t, Mapping)]
    if scales is not None or proportions is not None:
        sized = [t for t in tables if "arms" in t]
        template = {k: v for k, v in (sized[0] if sized else {}).items() if k not in ("name", "arms")}

        def equal(t: Mapping[str, Any]) -> bool:
            arms_value = t["arms"]
            return not isinstance(arms_value, list) or len(arms_value) == 1 or arms_value[0] == arms_value[-1]

        equal_tables = [t for t in sized if equal(t)] if scales is None else \
            [{**template, "name": size_label(s, s), "arms": [s, s]} for s in scales]
        other_tables = [t for t in sized if not equal(t)] if proportions is None else \
            [{**template, "name": size_label(u, f), "arms": [u, f]} for u, f in proportions]
        tables = equal_tables + other_tables
    if conditions is not None:
        known = [str(t.get("name")) for t in tables]
        unknown = [name for name in conditions if name not in known]
        if unknown:
            raise ScenarioError(f"unknown condition(s) {', '.join(map(repr, unknown))}; the scenario's are: {', '.join(known)}")
        tables = [t for t in tables if t.get("name") in conditions]
    result["conditions"] = tables
    return result
