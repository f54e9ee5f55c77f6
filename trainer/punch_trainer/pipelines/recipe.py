"""`punch recipe`: a shipped policy made again by one command from its recipe file (recipes/*.toml).

A recipe is the whole chain that made a policy: `punch train` stages, each from an earlier one's policy, and soups
(`punch soup`) of several. Every stage runs A2C for a fixed number of updates, never for a wall-time budget, so a
stage run again gives the same policy (`punch train`'s `--a2c-time-budget-s 0`). The runner keeps each stage's run
in its own folder of the recipe's run directory and skips a stage already made with the same options, so an
interrupted recipe goes on where it stopped; a stage made another way can be handed in (`--use STAGE=FILE`).

The file (TOML):

    name = "straight"                       # the policy's name
    policy = "addons/punch_controller/policies/straight.onnx"   # the file it makes (`--install` copies it there)
    [train]                                 # `punch train` options of every stage (TrainArgs' fields)
    reward = "straight"
    [[stage]]                               # a training stage: its own TrainArgs fields, and
    name = "clean"
    style = "boxing_straight_ordered_clean" # `none`, `boxing`, or a table of the recipe's styles.toml
    seed = 45
    a2c_updates = 600
    init_from_policy = "ordered_floor"      # start from an earlier stage's policy file (the actor; a critic is
                                            # fitted), or `init_from` its checkpoint (actor and critic), or a file
    take = "last"                           # the policy after the last update ("last", the default) or the one
                                            # A2C's validation chose ("best")
    [[stage]]                               # a soup: the mean of earlier stages' policies (learn/soup.py)
    name = "shipped"
    soup = ["ordered_floor", "clean", ...]

The last stage's policy is the recipe's: `RUN_DIR/policy.onnx`, with `RUN_DIR/report.md` listing every stage.
"""

from __future__ import annotations

import dataclasses
import hashlib
import shutil
import time
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from punch_trainer.errors import PunchError
from punch_trainer.learn.checkpoint import CONFIG_FILE, stored_config
from punch_trainer.learn.soup import soup
from punch_trainer.pipelines.train import TrainArgs, run_train
from punch_trainer.policy_file import read_policy_metadata
from punch_trainer.reward.style import STYLES, StyleError, style_named
from punch_trainer.sim.backend import LOCAL, Backend

STYLE_FILE = "styles.toml"
"""the recipe's own styles, beside the recipe files"""
MANAGED = ("out", "init_from", "a2c_time_budget_s", "a2c_snapshot_every")
"""TrainArgs fields the runner sets itself: a recipe names its stages' sources and fixes their updates"""


class RecipeError(PunchError):
    """A recipe that cannot be read or run: a malformed file, an unknown option or stage, a stage folder made
    with other options."""


@dataclass(frozen=True)
class TrainStage:
    """A `punch train` run of a recipe."""

    name: str
    args: dict[str, Any]
    """its TrainArgs fields, the recipe's [train] table with its own on top"""
    source: str | None
    """the stage or file it starts from (None: from its own search and pretraining)"""
    source_is_policy: bool
    """start from `source`'s policy file (the actor only) rather than its checkpoint"""
    take: Literal["last", "best"]

    @property
    def updates(self) -> int:
        return int(self.args["a2c_updates"])


@dataclass(frozen=True)
class SoupStage:
    """A `punch soup` of earlier stages' policies."""

    name: str
    ingredients: tuple[str, ...]


Stage = TrainStage | SoupStage


@dataclass(frozen=True)
class Recipe:
    path: Path
    name: str
    policy: Path
    """the file the recipe makes, relative to the repository root (where `punch recipe` runs)"""
    stages: tuple[Stage, ...]

    @property
    def guard(self) -> str:
        """The guard its policy punches from (the last training stage's `guard`): "square" for a policy of every
        start, "orthodox" for a rear hand's move, "southpaw" for a lead hand's (`punch train --guard`)."""
        last = [stage for stage in self.stages if isinstance(stage, TrainStage)][-1]
        return str(last.args.get("guard", TrainArgs.guard))

    def stage(self, name: str) -> Stage:
        for stage in self.stages:
            if stage.name == name:
                return stage
        raise RecipeError(f"{self.path}: no stage '{name}' (its stages: {', '.join(s.name for s in self.stages)})")


def load_recipe(path: Path) -> Recipe:
    """Reads and checks a recipe file: every option a TrainArgs field, every source an earlier stage or an existing
    file, every style known."""
    path = Path(path)
    try:
        document = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
        raise RecipeError(f"{path}: not a readable recipe ({error})") from None
    unknown_keys = sorted(set(document) - {"name", "policy", "train", "stage"})
    if unknown_keys:
        raise RecipeError(f"{path}: unknown entries {', '.join(unknown_keys)} (a recipe has name, policy, [train] and [[stage]]s)")
    for key in ("name", "policy"):
        if not isinstance(document.get(key), str):
            raise RecipeError(f"{path}: its '{key}' must be a string")
    common = document.get("train", {})
    tables = document.get("stage", [])
    if not isinstance(common, dict) or not isinstance(tables, list) or not tables:
        raise RecipeError(f"{path}: a recipe needs a [train] table and at least one [[stage]]")
    stages: list[Stage] = []
    for table in tables:
        stage = _read_stage(path, table, common, stages)
        if any(earlier.name == stage.name for earlier in stages):
            raise RecipeError(f"{path}: two stages are named '{stage.name}'")
        stages.append(stage)
    return Recipe(path, document["name"], Path(document["policy"]), tuple(stages))


def _read_stage(path: Path, table: Any, common: Mapping[str, Any], earlier: list[Stage]) -> Stage:
    if not isinstance(table, dict) or not isinstance(table.get("name"), str):
        raise RecipeError(f"{path}: every [[stage]] needs a name")
    name = table["name"]
    where = f"{path}, stage '{name}'"

    def source(value: Any) -> str:
        if not isinstance(value, str):
            raise RecipeError(f"{where}: a source is the name of an earlier stage or a policy file, not {value!r}")
        if any(stage.name == value for stage in earlier):
            return value
        if value.endswith(".onnx") and (path.parent / value).is_file():
            return value
        raise RecipeError(f"{where}: '{value}' is neither an earlier stage nor a policy file beside the recipe")

    if "soup" in table:
        if set(table) != {"name", "soup"} or not isinstance(table["soup"], list) or len(table["soup"]) < 2:
            raise RecipeError(f"{where}: a soup stage has only a name and `soup`, a list of at least two sources")
        return SoupStage(name, tuple(source(value) for value in table["soup"]))
    own = {key: value for key, value in table.items() if key not in ("name", "init_from", "init_from_policy", "take")}
    args = {**common, **own}
    fields = {field.name for field in dataclasses.fields(TrainArgs)}
    unknown = sorted(set(args) - fields)
    managed = sorted(set(args) & set(MANAGED))
    if unknown or managed:
        raise RecipeError(f"{where}: {', '.join(unknown + managed)} is not a recipe's to set "
                          f"({'the runner sets ' + ', '.join(MANAGED) if managed else 'not a punch train option'})")
    if not isinstance(args.get("a2c_updates"), int) or args["a2c_updates"] < 1:
        raise RecipeError(f"{where}: a2c_updates must be a whole number >= 1 (a recipe fixes its updates, so a stage "
                          "run again gives the same policy)")
    style = args.get("style", TrainArgs.style)
    try:
        style_named(recipe_style(path, style))
    except (StyleError, TypeError):
        raise RecipeError(f"{where}: style {style!r} is neither a product style ({', '.join(STYLES)}) nor one of "
                          f"{path.parent / STYLE_FILE}") from None
    if "init_from" in table and "init_from_policy" in table:
        raise RecipeError(f"{where}: start from init_from or init_from_policy, not both")
    start = table.get("init_from", table.get("init_from_policy"))
    start_source = None if start is None else source(start)
    if start_source is not None and "init_from" in table:
        started = next((stage for stage in earlier if stage.name == start_source), None)
        if not isinstance(started, TrainStage):
            raise RecipeError(f"{where}: init_from takes a training stage's checkpoint; start from a soup or a file "
                              "with init_from_policy")
    take = table.get("take", "last")
    if take not in ("last", "best"):
        raise RecipeError(f"{where}: take is 'last' or 'best', not {take!r}")
    return TrainStage(name, args, start_source, "init_from_policy" in table, take)


def recipe_style(recipe_path: Path, style: str) -> str:
    """The `--style` of a recipe's style: a product style or `FILE.toml:NAME` as it is, any other name a table of
    the recipe's styles.toml."""
    return style if style in STYLES or ":" in style else f"{recipe_path.parent / STYLE_FILE}:{style}"


def stage_train_args(recipe: Recipe, stage: TrainStage, run_dir: Path, sources: Mapping[str, Path]) -> TrainArgs:
    """The `punch train` arguments of a training stage, given the folders or files its sources were made in."""
    args = {**stage.args, "style": recipe_style(recipe.path, stage.args.get("style", TrainArgs.style))}
    init_from = None
    if stage.source is not None:
        made = sources.get(stage.source)
        if made is None:  # a file beside the recipe
            init_from = recipe.path.parent / stage.source
        elif stage.source_is_policy and made.suffix != ".onnx":
            init_from = made / "policy.onnx"
        else:
            init_from = made
    return TrainArgs(**args, out=run_dir / stage.name, init_from=init_from, a2c_time_budget_s=0.0,
                     a2c_snapshot_every=stage.updates if stage.take == "last" else 0)


def stage_output(stage: TrainStage, run: Path) -> Path:
    """Where a training stage's result lies: the snapshot folder after its last update (holding policy.onnx and a
    checkpoint), or the run folder, whose policy is the one A2C's validation chose."""
    return run / "a2c" / "snapshots" / f"update_{stage.updates:05d}" if stage.take == "last" else run


def command_line(args: TrainArgs) -> str:
    """The `punch train` command a stage runs, for `--dry-run` and the report."""
    defaults = TrainArgs()
    parts = ["punch train"]
    for field in dataclasses.fields(TrainArgs):
        value = getattr(args, field.name)
        if value != getattr(defaults, field.name) or field.name in ("reward", "style", "seed", "a2c_updates", "a2c_time_budget_s"):
            shown = " ".join(map(str, value)) if isinstance(value, list) else (f"{value:g}" if isinstance(value, float) else value)
            parts.append(f"--{field.name.replace('_', '-')} {shown}")
    return " ".join(parts)


@dataclass
class StageResult:
    name: str
    command: str
    output: Path
    seconds: float
    reused: bool


def run_recipe(recipe: Recipe, run_dir: Path, *, use: Mapping[str, Path] | None = None, until: str | None = None,
               dry_run: bool = False, progress: bool = True, backend: Backend = LOCAL,
               say: Callable[[str], None] = print) -> list[StageResult]:
    """Runs the recipe's stages in order into `run_dir` (up to and with `until`), each skipped when its folder
    already holds it (made with the same options) or when `use` hands in its policy file. Writes
    `run_dir/policy.onnx` and `run_dir/report.md` once the last stage is made. `dry_run` only says what would run."""
    use = dict(use or {})
    for name, file in use.items():
        recipe.stage(name)
        if not Path(file).is_file():
            raise RecipeError(f"--use {name}={file}: no such policy file")
    target = recipe.stage(until) if until is not None else recipe.stages[-1]
    needed = needed_stages(recipe, target.name, set(use))
    made: dict[str, Path] = {}
    results: list[StageResult] = []
    for index, stage in enumerate(recipe.stages, start=1):
        started = time.perf_counter()
        heading = f"[{index}/{len(recipe.stages)}] {stage.name}"
        if stage.name not in needed:
            say(f"{heading}: not needed (what it feeds was handed in, or comes after --until)")
            continue
        if stage.name in use:
            made[stage.name] = Path(use[stage.name])
            results.append(StageResult(stage.name, f"(handed in: {use[stage.name]})", made[stage.name], 0.0, True))
            say(f"{heading}: handed in, {use[stage.name]}")
        elif isinstance(stage, SoupStage):
            files = [policy_file(made[source]) if source in made else recipe.path.parent / source for source in stage.ingredients]
            out = run_dir / stage.name / "policy.onnx"
            command = f"punch soup {' '.join(map(str, files))} --out {out}"
            say(f"{heading}: {command}")
            reused = False
            if not dry_run:
                reused = out.is_file() and _soup_ingredients(out) == [_sha256(file) for file in files]
                if not reused:
                    soup(files, out)
            made[stage.name] = out
            results.append(StageResult(stage.name, command, out, time.perf_counter() - started, reused))
        else:
            args = stage_train_args(recipe, stage, run_dir, made)
            command = command_line(args)
            output = stage_output(stage, run_dir / stage.name)
            say(f"{heading}: {command}")
            reused = False
            if not dry_run:
                started_before = (run_dir / stage.name / CONFIG_FILE).is_file()
                if started_before:
                    _check_same_options(args)
                reused = started_before and policy_file(output).is_file() and (run_dir / stage.name / "report.md").is_file()
                if not reused:
                    run_train(args, progress=progress, resume=started_before, backend=backend)
                    if not policy_file(output).is_file():
                        raise RecipeError(f"stage '{stage.name}' ended without {policy_file(output)}")
            made[stage.name] = output
            results.append(StageResult(stage.name, command, output, time.perf_counter() - started, reused))
        if stage.name == until:
            return results
    if not dry_run:
        final = policy_file(made[recipe.stages[-1].name])
        run_dir.mkdir(parents=True, exist_ok=True)  # every stage handed in: none made the folder
        shutil.copyfile(final, run_dir / "policy.onnx")
        write_report(recipe, run_dir, results)
    return results


def needed_stages(recipe: Recipe, target: str, handed_in: set[str]) -> set[str]:
    """The stages `target` is made from (itself included), not looking past a stage that was handed in."""
    needed, waiting = set(), [target]
    while waiting:
        name = waiting.pop()
        if name in needed:
            continue
        needed.add(name)
        if name in handed_in:
            continue
        stage = recipe.stage(name)
        sources = stage.ingredients if isinstance(stage, SoupStage) else (stage.source,) if stage.source else ()
        waiting += [source for source in sources if any(s.name == source for s in recipe.stages)]
    return needed


def policy_file(output: Path) -> Path:
    """The policy file of a stage's result (a file handed in, a soup's, or a run's or snapshot's folder)."""
    return output if output.suffix == ".onnx" else output / "policy.onnx"


def _check_same_options(args: TrainArgs) -> None:
    """A stage folder from an earlier run of the recipe continues only if it was started with these options."""
    assert args.out is not None
    stored = stored_config(args.out)
    wanted = {key: (str(value) if isinstance(value, Path) else value) for key, value in dataclasses.asdict(args).items()}
    differing = sorted(key for key, value in wanted.items() if key in stored and stored[key] != value and key != "out")
    if differing:
        raise RecipeError(f"{args.out} was made with other options ({', '.join(differing)}); remove it or choose "
                          "another --out")


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _soup_ingredients(path: Path) -> list[str]:
    """The SHA-256s of the ingredients a soup file records (empty if it records none)."""
    summary = read_policy_metadata(path).training_summary or {}
    return [str(ingredient.get("sha256")) for ingredient in summary.get("soup", [])]


def write_report(recipe: Recipe, run_dir: Path, results: list[StageResult]) -> Path:
    """run_dir/report.md: each stage's command, its time and its policy's SHA-256."""
    lines = [f"# punch recipe: {recipe.name}", "", f"Recipe `{recipe.path}`; the policy: `policy.onnx` (SHA-256 "
             f"`{_sha256(run_dir / 'policy.onnx')}`), to be copied to `{recipe.policy}`.", "",
             "| stage | command | wall time (s) | policy SHA-256 |", "|---|---|---|---|"]
    for result in results:
        seconds = "made before" if result.reused else f"{result.seconds:.0f}"
        lines.append(f"| {result.name} | `{result.command}` | {seconds} | `{_sha256(policy_file(result.output))[:16]}` |")
    path = run_dir / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
