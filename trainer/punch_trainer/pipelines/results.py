"""`punch results`: every shipped policy measured by the one evaluator, written where the docs read it.

The figures the docs give of the shipped policies are made here, never copied: each recipe's policy is played through
the evaluator's scenarios below, the reports go into BENCHMARKS.md (one section per policy) and a summary table of
them into BENCHMARKS.md's "The shipped policies" and into the policies' README (between its `punch results`
markers). When every policy of the stance's moveset (`boxing_stance.tres`) was measured, BENCHMARKS.md's "The six moves" gives each move's
success from the stance's guard (head and body) and its shape against a boxer's (`MOVE_TARGETS`). Run it again after
a policy changes (`punch recipe ... --install`).
"""

from __future__ import annotations

import datetime
import hashlib
import json
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from punch_trainer.errors import PunchError
from punch_trainer.pipelines.evaluation import EvalArgs, benchmarks_body, run_eval
from punch_trainer.pipelines.recipe import Recipe, load_recipe
from punch_trainer.pipelines.scenario import LEAD_MOVES, load_scenario, scenario_path
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.godot import PROJECT_ROOT

RECIPES_DIR = PROJECT_ROOT / "recipes"
POLICIES_README = PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "README.md"
MOVESET = PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "boxing.tres"
STANCE_MOVESET = MOVESET.with_name("boxing_stance.tres")
"""the moveset for a character in the stance's guard (`stance_pose`): the moves a policy of the square guard does not
throw well from there played by policies trained from that guard (`punch train --guard`)"""
EXTENSION_LIBRARY = PROJECT_ROOT / "addons" / "punch_controller" / "bin" / "libpunch_controller.linux.debug.x86_64.so"
"""the extension headless Godot plays the measurements with (its debug build)"""
EVALUATOR_DRIVER = PROJECT_ROOT / "godot_project" / "tools" / "evaluate.gd"
"""the script that plays every measurement's punches in headless Godot"""
SUMMARY_SECTION = "The shipped policies"
MOVES_SECTION = "The six moves"
SUMMARY_MARKERS = ("<!-- punch results:start -->", "<!-- punch results:end -->")


class ResultsError(PunchError):
    """A shipped policy that cannot be measured: no recipe, or its policy file missing."""


@dataclass(frozen=True)
class Measurement:
    """One evaluator run of every shipped policy: a scenario and the options that size it."""

    scenario: str
    options: dict[str, Any] = field(default_factory=dict)
    """EvalArgs fields beside the scenario's own"""
    move: str | None = None
    """a default-moveset measurement played with this move's policy (its scenario throws that policy's moves); None:
    the moveset's jab's, which only gives the placements' volume"""

    def args(self, policy: Path, out: Path) -> EvalArgs:
        return EvalArgs(policy=policy, scenario=self.scenario, out=out, **self.options)

    def command(self, policy: Path) -> str:
        words = ["punch", "eval", "--policy", str(policy), "--scenario", self.scenario]
        for key, value in self.options.items():
            words.append("--" + key.replace("_", "-"))
            if key == "conditions":
                words += value  # one argument per condition's name
            elif isinstance(value, list):
                words.append(",".join(f"{v:g}" for v in value))
            else:
                words.append(str(value))
        return shlex.join(words)


MEASUREMENTS = (
    # Success under noise and the naturalness figures, over 2,048 placements of the reach volume no stage trained on.
    Measurement("held_out", {"placements": 2048, "seed": 2025, "sigmas": [0.0, 0.3], "search_iterations": 0,
                             "conditions": ["every decision"]}),
    Measurement("moving"),
    Measurement("sizes", {"placements": 256}),
    # The policy thrown with the left hand (mirrored) beside the right, at mirrored held-out placements.
    Measurement("hands", {"placements": 1024, "seed": 2025}),
    # From the stance's guard (`stance_pose`), as the rear and the lead hand's move in each stance: at the head (the
    # volume) and at the body (targets 1.00-1.20 m high).
    Measurement("stance", {"placements": 2048}),
    Measurement("body", {"placements": 2048}),
    # From the stance's guard walking, turning and with sized arms, as the rear and the lead hand's move.
    Measurement("stance_moving"),
)

GUARD_HANDS = {"orthodox": "rear", "southpaw": "lead"}
"""the hand a policy trained from one stance's guard punches with (`punch train --guard`): the right hand from the
orthodox guard is the rear hand; from the southpaw guard, the lead"""
STANCE_SCENARIOS = ("stance", "body", "stance_moving")


def measurements_for(recipe: Recipe) -> tuple[Measurement, ...]:
    """What a recipe's policy is measured by: every measurement for a policy of every start (the square guard's); for
    a policy of one stance's guard, the stance scenarios alone, with only its hand's conditions (the square guard's
    scenarios ask what it was not made for)."""
    if recipe.guard not in GUARD_HANDS:
        return MEASUREMENTS
    hand = GUARD_HANDS[recipe.guard]
    return tuple(Measurement(m.scenario, {**m.options, "conditions": [c.name for c in load_scenario(m.scenario).conditions
                                                                       if c.name.startswith(f"{hand} hand")]})
                 for m in MEASUREMENTS if m.scenario in STANCE_SCENARIOS)


MOVESET_MEASUREMENTS = (
    # Combinations thrown with combo(), every move alone (startup and recovery), and a punch started at a random
    # moment of another's recovery, with the default moveset.
    Measurement("combos"),
    Measurement("frame_data"),
    Measurement("from_recovery"),
    # The standing character struck by the game: its reaction and its way back to guard (HITS_SECTION) ...
    Measurement(HITS_SCENARIO := "hits"),
    # ... and blocking: jabs and crosses at the head of a second character that blocks or stands in guard, then the
    # moveset's hooks and uppercuts the same way.
    Measurement(BLOCKS_SCENARIO := "blocks"),
    Measurement(BLOCKS_HOOKS_SCENARIO := "blocks_hooks", move="lead_hook"),
    Measurement(BLOCKS_UPPERCUTS_SCENARIO := "blocks_uppercuts", move="lead_uppercut"),
)
MOVESET_KEY = "moveset"
"""`measure`'s key (and output folder) of the default moveset's measurements"""
COMBOS_SECTION = "Combos and frame data"
HITS_SECTION = "Taking hits"

SIX_MOVES = ("jab", "cross", "lead_hook", "rear_hook", "lead_uppercut", "rear_uppercut")


@dataclass(frozen=True)
class MoveTarget:
    """What a boxer's move looks like, as a naturalness figure's range (docs/moves.md; None: no bound)."""

    figure: str
    low: float | None
    high: float | None
    moves: tuple[str, ...] = SIX_MOVES

    def met(self, value: float | None) -> bool:
        return value is not None and (self.low is None or value >= self.low) and (self.high is None or value <= self.high)

    def label(self) -> str:
        if self.low is None:
            return f"{self.figure} <= {self.high:g}"
        return f"{self.figure} >= {self.low:g}" if self.high is None else f"{self.figure} {self.low:g}-{self.high:g}"


HOOKS, UPPERCUTS = ("lead_hook", "rear_hook"), ("lead_uppercut", "rear_uppercut")
MOVE_TARGETS = (
    MoveTarget("time_to_contact_s", None, 0.25, ("jab",)),
    MoveTarget("path_over_chord", None, 1.2, ("jab",)),
    MoveTarget("fist_peak_speed_mps", 5.0, 8.0, ("jab",)),
    MoveTarget("path_over_chord", None, 1.3, ("cross",)),
    MoveTarget("fist_peak_speed_mps", 6.0, 10.0, ("cross",)),
    MoveTarget("side_angle_at_contact_deg", 35.0, None, HOOKS),
    MoveTarget("elbow_bend_at_contact_deg", 70.0, 120.0, HOOKS),
    MoveTarget("rise_share_at_contact", 0.5, None, UPPERCUTS),
    MoveTarget("elbow_bend_at_contact_deg", 60.0, 120.0, UPPERCUTS),
    MoveTarget("off_fist_from_guard_m", None, 0.20),
    MoveTarget("trunk_flexion_deg", None, 20.0),
)
"""A boxer's moves (the jab short and quick, the hooks sweeping in from the side, the uppercuts rising), each figure
from the stance's guard at sigma 0, its median. Besides: a hook's fist at least as fast as the cross's, and the jab
the quickest of the six to land."""


def moveset_policies(path: Path = MOVESET) -> dict[str, str]:
    """The default moveset's policy file (its name) for each move, read from its .tres as Godot writes it."""
    text = path.read_text()
    files = {id_: Path(file).name for file, id_ in re.findall(r'\[ext_resource [^\]]*path="([^"]+)" id="([^"]+)"\]', text)}
    moves = {move: files[id_] for move, id_ in re.findall(r'^(\w+) = ExtResource\("([^"]+)"\)', text, re.M) if id_ in files}
    missing = [move for move in SIX_MOVES if move not in moves]
    if missing:
        raise ResultsError(f"{path}: no policy for {', '.join(missing)}")
    return moves


def shipped_recipes(recipes_dir: Path = RECIPES_DIR) -> list[Recipe]:
    """The recipes of the shipped policies, by name."""
    recipes = [load_recipe(path) for path in sorted(recipes_dir.glob("*.toml")) if path.name != "styles.toml"]
    if not recipes:
        raise ResultsError(f"no recipe in {recipes_dir}")
    return recipes


MEASURED_FILE = "measured.json"
"""beside a measurement's report: the policy's SHA-256 and the command it was measured with"""


def measure(recipes: list[Recipe], out: Path, *, progress: bool = True, backend: Backend = LOCAL) -> dict[str, list[dict[str, Any]]]:
    """Every measurement of every recipe's policy: {recipe name: [the evaluator's report, one per measurement]}, and
    the default moveset's (`MOVESET_MEASUREMENTS`) under `MOVESET_KEY`. Each run's report.md and plots stay in
    `out/<name>/<scenario>`; a measurement already there of the same policy files, extension build and evaluator
    driver (their SHA-256) by the same command is read back instead of played again, so after one policy changes
    only its measurements run."""
    reports: dict[str, list[dict[str, Any]]] = {}
    # The controller that plays the punches, and the driver that plays them, are measured too: a rebuilt extension
    # or a changed driver measures again.
    instruments = {"extension_sha256": sha256_of(EXTENSION_LIBRARY)} if EXTENSION_LIBRARY.is_file() else {}
    instruments["evaluator_sha256"] = sha256_of(EVALUATOR_DRIVER)
    for recipe in recipes:
        policy = PROJECT_ROOT / recipe.policy
        if not policy.is_file():
            raise ResultsError(f"{recipe.path}: its policy {recipe.policy} is missing (make it: punch recipe {recipe.path} --install)")
        stamp = {"policy_sha256": sha256_of(policy), **instruments}
        reports[recipe.name] = [_measured(measurement, recipe.policy, out / recipe.name / measurement.scenario, stamp,
                                          progress, backend) for measurement in measurements_for(recipe)]
    # The moveset's combos play every move's policy: its measurements are stamped with all of them.
    policies = moveset_policies()
    files = sorted(set(policies.values()) | set(moveset_policies(STANCE_MOVESET).values()))
    stamp = {"moveset_sha256": sha256_of(MOVESET), "stance_moveset_sha256": sha256_of(STANCE_MOVESET), **instruments,
             **{f"{name}_sha256": sha256_of(MOVESET.parent / name) for name in files}}
    def policy_of(measurement: Measurement) -> Path:
        return (MOVESET.parent / policies[measurement.move or "jab"]).relative_to(PROJECT_ROOT)

    reports[MOVESET_KEY] = [_measured(measurement, policy_of(measurement), out / MOVESET_KEY / measurement.scenario, stamp,
                                      progress, backend) for measurement in MOVESET_MEASUREMENTS]
    return reports


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _measured(measurement: Measurement, policy: Path, run_dir: Path, stamp: dict[str, str], progress: bool,
              backend: Backend) -> dict[str, Any]:
    """One measurement, read back when `run_dir` holds one with the same stamp and command, else played."""
    # The scenario's file too: a condition added to it is measured, not read back.
    wanted = {**stamp, "scenario_sha256": sha256_of(scenario_path(measurement.scenario)), "command": measurement.command(policy)}
    measured = run_dir / MEASURED_FILE
    if measured.is_file() and json.loads(measured.read_text()) == wanted and (run_dir / "eval.json").is_file():
        report = json.loads((run_dir / "eval.json").read_text())
        if progress:
            print(f"{run_dir.parent.name} {measurement.scenario}: measured before ({run_dir})", flush=True)
    else:
        measured.unlink(missing_ok=True)
        run_dir, report = run_eval(measurement.args(PROJECT_ROOT / policy, run_dir), progress, backend=backend)
        measured.write_text(json.dumps(wanted) + "\n")
    measured_at = datetime.datetime.fromtimestamp((run_dir / "eval.json").stat().st_mtime, datetime.UTC)
    return {"measurement": measurement, "report": report, "markdown": (run_dir / "report.md").read_text(), "measured": measured_at,
            "command": wanted["command"]}


def _rows(report: dict[str, Any]) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = report["evaluations"][0]["rows"]
    return rows


def summary_row(recipe: Recipe, runs: list[dict[str, Any]]) -> list[str]:
    """The figures that matter of one policy, from its reports: held-out success at sigma 0 and 0.3, the share in
    proximal-to-distal order and the fist's peak speed at sigma 0, the weakest arm size, the hits on the move and the
    left hand's success at sigma 0.3 and the weakest move from the stance's guard at sigma 0.3; "-" where a policy of
    one stance's guard was not measured (`measurements_for`)."""
    by_scenario = {run["measurement"].scenario: run["report"] for run in runs}

    def success(rows: list[dict[str, Any]], sigma: float) -> tuple[int, int]:
        chosen = [row for row in rows if abs(row["sigma"] - sigma) < 1e-9]
        return sum(row["successes"] for row in chosen), sum(row["punches"] for row in chosen)

    def percent(counts: tuple[int, int]) -> str:
        return f"{100 * counts[0] / counts[1]:.1f}% of {counts[1]:,}"

    stance = by_scenario["stance"]
    from_stance = min((row for row in _rows(stance) if row["sigma"] == 0.3), key=lambda row: row["success_rate"])
    cells = [f"`{recipe.policy.name}`", f"[{recipe.path.relative_to(PROJECT_ROOT).as_posix()}]"]
    if "held_out" not in by_scenario:
        return [*cells, *["-"] * 7, f"{100 * from_stance['success_rate']:.1f}% ({from_stance['condition']})"]
    held_out, moving, sizes, hands = (by_scenario[name] for name in ("held_out", "moving", "sizes", "hands"))
    natural = next(n for n in held_out["evaluations"][0]["naturalness"] if n["sigma"] == 0.0)
    weakest = min((row for row in _rows(sizes) if row["sigma"] == 0.0), key=lambda row: row["success_rate"])
    moved = success(_rows(moving), 0.0)
    left_hand = success([row for row in _rows(hands) if row["condition"].startswith("left")], 0.3)
    return [*cells, percent(success(_rows(held_out), 0.0)), percent(success(_rows(held_out), 0.3)),
            f"{100 * natural['proximal_to_distal_share']:.0f}%", f"{natural['medians']['fist_peak_speed_mps']:.2f} m/s",
            f"{100 * weakest['success_rate']:.1f}% (arms {weakest['condition']})", f"{moved[0]:,} of {moved[1]:,}",
            percent(left_hand), f"{100 * from_stance['success_rate']:.1f}% ({from_stance['condition']})"]


SUMMARY_HEADER = ["file", "recipe", "lands at sigma 0 (held out)", "at sigma 0.3", "in proximal-to-distal order, sigma 0",
                  "fist peak speed, sigma 0", "weakest arm size, sigma 0", "hits on the move, sigma 0",
                  "left hand (mirrored), sigma 0.3", "weakest from the stance's guard, sigma 0.3"]


def summary_table(rows: list[list[str]], link_prefix: str) -> str:
    """The summary as Markdown; the recipe cells link through `link_prefix` (the path from the file that shows it
    to the repository root)."""
    lines = ["| " + " | ".join(SUMMARY_HEADER) + " |", "|" + "---|" * len(SUMMARY_HEADER)]
    for row in rows:
        recipe = row[1].strip("[]")
        lines.append("| " + " | ".join([row[0], f"[{recipe}]({link_prefix}{recipe})", *row[2:]]) + " |")
    return "\n".join(lines)


def hand_row(move: str, stance: str) -> str:
    """How the scenarios' rows for a move's hand begin: `{lead|rear} hand, {stance}` in `stance` and `body` (the
    rest names the hand, which the controller's `hand_for` gave the evaluator), `{lead|rear} hand, {kind}` in
    `stance_moving` (kind: `moving` or `arms`)."""
    return f"{'lead' if move in LEAD_MOVES else 'rear'} hand, {stance}"


def moves_table(reports: dict[str, list[dict[str, Any]]], policy_recipes: dict[str, str],
                moveset_file: Path = STANCE_MOVESET) -> str | None:
    """Each move of the stance's moveset from the stance's guard: its success at the head and the body (the lower of the
    two stances), its naturalness medians (orthodox, sigma 0) and the targets it misses; None unless every policy of the
    moveset was measured. `policy_recipes`: policy file name -> recipe name."""
    moveset = moveset_policies(moveset_file)
    recipe_of = {move: policy_recipes.get(file) for move, file in moveset.items()}
    if any(name is None or name not in reports for name in recipe_of.values()):
        return None

    def report(move: str, scenario: str) -> dict[str, Any]:
        return next(run["report"] for run in reports[str(recipe_of[move])] if run["measurement"].scenario == scenario)

    def lands(move: str, scenario: str, sigma: float, kinds: tuple[str, ...] = ("orthodox", "southpaw")) -> str:
        rows = [row for row in _rows(report(move, scenario)) if abs(row["sigma"] - sigma) < 1e-9
                and row["condition"].startswith(tuple(hand_row(move, kind) for kind in kinds))]
        cell = f"{100 * min(row['success_rate'] for row in rows):.1f}%"
        if not any(row["out_of_reach"] for row in rows):
            return cell
        # The controller said some targets lay beyond the character's reach (`target_out_of_reach`): a game steps in.
        in_reach = [row["in_reach_successes"] / (row["punches"] - row["out_of_reach"])
                    for row in rows if row["punches"] > row["out_of_reach"]]
        return cell + (f" ({100 * min(in_reach):.1f}% in reach)" if in_reach else " (none in reach)")

    def medians(move: str) -> dict[str, Any]:
        natural = report(move, "stance")["evaluations"][0]["naturalness"]
        row = next(n for n in natural if n["condition"].startswith(hand_row(move, "orthodox")) and n["sigma"] == 0.0)
        figures: dict[str, Any] = row["medians"]
        return figures

    figures = {move: medians(move) for move in SIX_MOVES}
    shown = (("time_to_contact_s", "{:.3f} s"), ("path_over_chord", "{:.2f}"), ("fist_peak_speed_mps", "{:.2f} m/s"),
             ("side_angle_at_contact_deg", "{:.0f}°"), ("rise_share_at_contact", "{:.2f}"),
             ("elbow_bend_at_contact_deg", "{:.0f}°"), ("off_fist_from_guard_m", "{:.2f} m"), ("trunk_flexion_deg", "{:.0f}°"))
    header = ["move", "policy", "head, sigma 0", "head, 0.3", "body, sigma 0", "body, 0.3", "on the move, sigma 0",
              "arms 0.75 and 1.25, sigma 0", "time to contact", "path/chord",
              "fist peak speed", "side approach", "rising share", "elbow bend", "off fist from guard", "waist flexion",
              "a boxer's shape: missed"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    times = {move: figures[move]["time_to_contact_s"] for move in SIX_MOVES}
    for move in SIX_MOVES:
        missed = [target.label() for target in MOVE_TARGETS if move in target.moves and not target.met(figures[move][target.figure])]
        if move in HOOKS and (figures[move]["fist_peak_speed_mps"] or 0.0) < (figures["cross"]["fist_peak_speed_mps"] or 0.0):
            missed.append("fist_peak_speed_mps >= the cross's")
        if move == "jab" and any(time is not None and time < (times["jab"] or float("inf")) for other, time in times.items() if other != "jab"):
            missed.append("the quickest to land")
        cells = [f"`{move}`", f"`{moveset[move]}`", *(lands(move, scenario, sigma) for scenario in ("stance", "body") for sigma in (0.0, 0.3)),
                 lands(move, "stance_moving", 0.0, ("moving",)), lands(move, "stance_moving", 0.0, ("arms",)),
                 *("-" if figures[move][key] is None else form.format(figures[move][key]) for key, form in shown),
                 ", ".join(missed) or "none"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _repository_paths(report_md: str) -> str:
    """A report with the files of this checkout named from its root, the same on every machine."""
    return report_md.replace(f"{PROJECT_ROOT}/", "")


def write_results(recipes: list[Recipe], reports: dict[str, list[dict[str, Any]]], command: str) -> list[Path]:
    """BENCHMARKS.md's summary and per-policy sections, the six moves' table, and the policies' README table."""
    from punch_trainer.pipelines.bench import BENCHMARKS_FILE, machine_description, write_section

    # The README is checked first, so a refused run leaves both files as they were.
    text = POLICIES_README.read_text()
    start, end = SUMMARY_MARKERS
    pattern = re.compile(rf"{re.escape(start)}.*?{re.escape(end)}", re.S)
    if not pattern.search(text):
        raise ResultsError(f"{POLICIES_README}: no {start} ... {end} markers for the table")
    rows = [summary_row(recipe, reports[recipe.name]) for recipe in recipes]
    scenarios = ", ".join(f"`{m.command(Path('POLICY'))}`" for m in MEASUREMENTS)
    explained = (f"Each shipped policy through the evaluator (docs/evaluation.md): {scenarios}. Held out: a hit and a "
                 "positive return, one punch per placement at sigma 0 and two at 0.3; on the move: the controller's "
                 "`hit` over every condition of the `moving` scenario; arm sizes: the fewest hits over the `sizes` "
                 "scenario's arms; the left hand: the `hands` scenario's southpaw row (the policy mirrored, at the mirror "
                 "images of its placements); from the stance: the `stance` scenario's lowest row at sigma 0.3. The reports of "
                 "each policy follow, one section each.")
    def oldest(names: list[str]) -> datetime.datetime | None:
        """When the oldest measurement of these recipes was made (a section's stamp, when some were read back)."""
        stamps: list[datetime.datetime] = [run["measured"] for name in names for run in reports[name]]
        return min(stamps, default=None)

    write_section(SUMMARY_SECTION, command, explained + "\n\n" + summary_table(rows, ""), oldest([r.name for r in recipes]))
    moves = moves_table(reports, {recipe.policy.name: recipe.name for recipe in recipes})
    if moves is not None:
        write_section(MOVES_SECTION, command, (
            "Each move of the stance's moveset (`boxing_stance.tres`, for a character with `stance_pose` on) from the "
            "stance's guard, both stances: the "
            "lower of the two stances' success at the head (the `stance` scenario) and the body (`body`, targets 1.00-1.20 "
            "m high); the lowest walking 0.7 or 1.4 m/s or turning 90°/s either way, and with arms 0.75 or 1.25 times the "
            "body's (`stance_moving`, orthodox: the southpaw's is its mirror image; in parentheses, where the controller said "
            "some targets lay beyond the character's reach, `target_out_of_reach`, the lowest success over those in reach), then its naturalness medians (orthodox, sigma 0; docs/naturalness.md) and the figures of a boxer's "
            "move it misses (docs/moves.md). Moves that share a policy differ by hand: the lead hand's from its side.\n\n"
            + moves), oldest([r.name for r in recipes]))
    if MOVESET_KEY in reports:
        body = ["The default moveset (`boxing.tres`; from the stance's guard, `boxing_stance.tres`) thrown as a game throws it: combinations with `combo()`, each punch "
                "starting at the one before's cancel window (its contact; the moveset's delays are 0) after a return near the "
                "guard (`guard_first`), each move alone for its frame data, and a second punch started at a random moment of the "
                "first's recovery from wherever the arms are (`from_recovery`; docs/combos.md). The `--policy` only gives the "
                "placements' volume; every move plays its own policy.", ""]
        hits = ["The addon's character (`punch_character.tscn`) in guard, standing (the last rows: walking or turning, "
                "or with sized arms), struck by the game (`PunchCharacter.take_hit`) and reacting with its controller's defaults (`react_to_hits`, "
                "`stagger_impulse_ns` 60, `knockdown_impulse_ns` 320; docs/hits.md). No punch is thrown; the `--policy` "
                "only places a sandbag nobody punches. Then blocking (`PunchController.block()`): the moveset's jab and "
                "cross at the head, and its cross at the body, of a second character of the addon's scene that blocks "
                "or stands in guard, then its hooks and its uppercuts the same way (docs/hits.md).", ""]
        for run in reports[MOVESET_KEY]:
            taking_hits = (HITS_SCENARIO, BLOCKS_SCENARIO, BLOCKS_HOOKS_SCENARIO, BLOCKS_UPPERCUTS_SCENARIO)
            part = hits if run["measurement"].scenario in taking_hits else body
            part += [f"### `{run['command']}`", "", *benchmarks_body(_repository_paths(run["markdown"]), depth=1), ""]
        write_section(COMBOS_SECTION, command, "\n".join(body).strip(), oldest([MOVESET_KEY]))
        write_section(HITS_SECTION, command, "\n".join(hits).strip(), oldest([MOVESET_KEY]))
    for recipe in recipes:
        body = []
        for run in reports[recipe.name]:
            body += [f"### `{run['measurement'].command(recipe.policy)}`", "",
                     *benchmarks_body(_repository_paths(run["markdown"]), depth=1), ""]
        write_section(f"The shipped {recipe.name}", command, "\n".join(body).strip(), oldest([recipe.name]))
    moves_link = (f"; each move of the default moveset: [BENCHMARKS.md, \"{MOVES_SECTION}\"](../../../BENCHMARKS.md#the-six-moves)"
                  if moves is not None else "")
    table = (f"{start}\n{summary_table(rows, '../../../')}\n\nMeasured by `{command}` on {machine_description()}; every "
             f"report: [BENCHMARKS.md, \"{SUMMARY_SECTION}\"](../../../BENCHMARKS.md#the-shipped-policies){moves_link}.\n{end}")
    POLICIES_README.write_text(pattern.sub(lambda _: table, text))
    return [BENCHMARKS_FILE, POLICIES_README]
