"""The `punch` command: parses the options (each command's come from its `*Args` dataclass: `cli/arguments.py`),
chooses where training servers run (`--ray`), runs a pipeline and prints what it found."""

from __future__ import annotations

import argparse
import contextlib
import os
import shlex
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar, Protocol, TypeVar

from punch_trainer import __version__
from punch_trainer.cli.arguments import add_dataclass_arguments, dataclass_from_arguments, field_docs
from punch_trainer.errors import PunchError
from punch_trainer.learn.checkpoint import read_config
from punch_trainer.learn.pretrain import PretrainArgs
from punch_trainer.learn.search import SearchArgs
from punch_trainer.pipelines.bench import BenchEnvArgs, BenchInferenceArgs, BenchSearchArgs, BenchSoakArgs
from punch_trainer.pipelines.evaluation import EvalArgs, parse_scales, parse_sigmas, parse_sizes
from punch_trainer.pipelines.experiments import AfterPunchArgs, Fig6Args
from punch_trainer.pipelines.render import RenderArgs, parse_bags
from punch_trainer.pipelines.replay import ReplayArgs
from punch_trainer.pipelines.selfcheck import SelfCheckArgs
from punch_trainer.pipelines.style_experiment import StyleExperimentArgs
from punch_trainer.pipelines.train import TrainArgs, reach_default_notes
from punch_trainer.sim.cluster import backend_for


class _RunArgs(Protocol):
    """What SearchArgs and TrainArgs share: dataclasses with an `out` run directory."""

    __dataclass_fields__: ClassVar[dict[str, Any]]
    out: Path | None

    def run_dir(self) -> Path: ...


RunArgsT = TypeVar("RunArgsT", bound=_RunArgs)


def _selfcheck(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.selfcheck import run_selfcheck

    report = run_selfcheck(dataclass_from_arguments(SelfCheckArgs, args))
    print("\n".join(report.lines()))
    print("Self-check passed.")
    return 0


def _bench_env(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.bench import bench_env, bench_ray, env_table, ray_tables, write_section

    bench_args, defaults = dataclass_from_arguments(BenchEnvArgs, args), BenchEnvArgs()
    if args.ray is not None:
        # K = 1 always: the projection starts from one worker's batch.
        processes = sorted({1, *bench_args.processes}) if bench_args.processes != defaults.processes else [1, 2, 3]
        with backend_for(args.ray) as backend:
            rows = bench_ray(backend, processes=processes, frames=bench_args.frames)
        table = ray_tables(rows, frames=bench_args.frames)
        print(table)
        if not args.no_write:
            note = ("Ray's cost against local processes at the same count K (`sim/cluster.py`): open-loop batches of 64 characters "
                    f"per worker, {bench_args.frames} frames each, timed on K local Godot processes and on K Ray workers, alternating "
                    "eight times in one run so both see the same machine (the medians of the eight). Goal: at most 10% overhead "
                    "at 64 characters per worker.")
            print(f"written to {write_section('Ray workers', f'punch bench env --ray {args.ray}', note + chr(10) + chr(10) + table)}")
        return 0

    results = bench_env(bench_args)
    table = env_table(results)
    print(table)
    if not args.no_write:
        same = (bench_args.characters, bench_args.processes) == (defaults.characters, defaults.processes)
        command = "punch bench env" + ("" if same else f" --characters {' '.join(map(str, bench_args.characters))} "
                                                       f"--processes {' '.join(map(str, bench_args.processes))}")
        note = ("Character-physics-frames per second through the real TCP socket, reset included, "
                f"{bench_args.frames}-frame episodes at 120 Hz. Open loop: one `rollout` message per episode; "
                "closed loop: `reset` then one `step` per decision.")
        print(f"written to {write_section('Env throughput', command, note + chr(10) + chr(10) + table)}")
    return 0


def _bench_inference(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.bench import IDLE_FRAMES, bench_inference, inference_table, write_section

    bench_args = dataclass_from_arguments(BenchInferenceArgs, args)
    rows = bench_inference(bench_args)
    table = inference_table(rows)
    print(table)
    if not args.no_write:
        command = "punch bench inference" + ("" if bench_args.policy == BenchInferenceArgs().policy else f" --policy {bench_args.policy}")
        note = (f"PunchController in headless Godot (the editor's debug build of the extension), {bench_args.batches} punches of 50 "
                "frames per controller at sigma 0.3, every controller sharing one policy (`" + os.path.relpath(bench_args.policy) + "`), so one ONNX "
                "Runtime call per decision tick. Inference time is measured around each call; the controller work is the whole "
                "per-frame pass over all controllers (sensing, observation, inference, noise, smoothing, motor commands), without "
                "the physics step. The last column is that work while the same characters stand idle (not punching, not "
                f"recovering) for {IDLE_FRAMES} frames after their punches, the median frame; characters that never punched run no "
                "per-frame code. "
                "Targets: at most 10 µs per character-decision when batched at 64 or more; under 1 ms of controller work per "
                "frame for 100 characters at 120 Hz.")
        print(f"written to {write_section('PunchController inference', command, note + chr(10) + chr(10) + table)}")
    return 0


def _search(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.search import run_search

    search_args = _run_args(args, SearchArgs)
    with _resume_hint("search", search_args.out), backend_for(args.ray) as backend:
        out, result, report = run_search(search_args, resume=args.resume is not None, backend=backend)
    print(f"best return {result.best_return:.4f} after {len(result.history)} iterations; "
          f"peak fist speed {report['peak_fist_speed_mps']:.2f} m/s")
    print(f"run directory: {out} (report: {out / 'report.md'})")
    return 0


def _bench_soak(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.bench import bench_soak, soak_body, write_section

    soak_args = dataclass_from_arguments(BenchSoakArgs, args)
    report = bench_soak(soak_args)
    body = soak_body(soak_args, report)
    print(body)
    if not args.no_write:
        command = "punch bench soak" + ("" if soak_args == BenchSoakArgs() else
                                        f" --pairs {soak_args.pairs} --seconds {soak_args.seconds:g} --seed {soak_args.seed}")
        print(f"written to {write_section('Soak', command, body)}")
    return 0 if report["problem_count"] == 0 else 1


def _bench_search(args: argparse.Namespace) -> int:
    import tempfile

    from punch_trainer.pipelines.bench import bench_search, search_table, write_section
    from punch_trainer.sim.godot import PROJECT_ROOT

    bench_args = dataclass_from_arguments(BenchSearchArgs, args)
    plot = Path(tempfile.mkdtemp()) / "bench_search.png" if args.no_write else PROJECT_ROOT / "docs" / "bench_search.png"
    rows = bench_search(bench_args, plot)
    table = search_table(rows)
    print(table)
    if not args.no_write:
        command = "punch bench search" + ("" if bench_args == BenchSearchArgs() else
                                         f" --presets {' '.join(bench_args.presets)} --seeds {' '.join(map(str, bench_args.seeds))} "
                                         f"--iterations {bench_args.iterations} --rollouts {bench_args.rollouts}")
        note = (f"Each method gets {bench_args.iterations} iterations of {bench_args.rollouts} rollouts (equal rollouts), on one "
                "process with 64 characters, with smoothing window 3. Target: TTR reaches 95% of its final return "
                "for `straight` in at most 20 s, and no baseline beats it at equal rollouts. TTR uses each preset's sigma "
                "clip: 0.2, and 0.1 for `swing`. In the first run, at 0.2, CMA-ES beat TTR on `swing` "
                "(284 against 234), and the slower narrowing fixed that.\n\n"
                "![return against rollouts and wall time](docs/bench_search.png)")
        print(f"written to {write_section('Trajectory search against baselines', command, note + chr(10) + chr(10) + table)} and {plot}")
    return 0


def _train(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.train import run_train

    train_args = _run_args(args, TrainArgs)
    with _resume_hint("train", train_args.out), backend_for(args.ray) as backend:
        out = run_train(train_args, resume=args.resume is not None, backend=backend)
    print((out / "report.md").read_text())
    print(f"report: {out / 'report.md'}")
    return 0


def _run_args(args: argparse.Namespace, args_type: type[RunArgsT]) -> RunArgsT:
    """The arguments of `punch search` or `punch train`: the run's own when resuming, else the command line's,
    with the run directory fixed now, so that an interruption can name it."""
    if args.resume is not None:
        resumed = read_config(args.resume, args_type)
        _check_resumed_reward(args.resume, str(getattr(resumed, "reward", "")), args.reward)
        return resumed
    if args.reward is None:
        args.reward = args_type.__dataclass_fields__["reward"].default
    run_args = dataclass_from_arguments(args_type, args)
    run_args.out = run_args.run_dir()
    return run_args


def _check_resumed_reward(run_dir: Path, recorded: str, named: str | None) -> None:
    """A resume runs no code the command line did not name: a run whose reward is a file or module needs
    `--reward` naming it again (and the search checks its source's SHA-256 against the run's); a --reward
    that is not the run's is refused."""
    from punch_trainer.learn.checkpoint import CheckpointError
    from punch_trainer.reward.rewards import PRESETS

    if named is not None and named != recorded:
        raise CheckpointError(f"{run_dir} is a run of the reward {recorded!r}; --resume continues it with that reward, "
                              f"not {named!r}")
    if named is None and recorded not in PRESETS:
        raise CheckpointError(f"{run_dir}'s reward {recorded!r} is code; a resume runs only code the command line names: "
                              f"add --reward {recorded} (its source must be the one the run started with)")


@contextlib.contextmanager
def _resume_hint(command: str, out: Path | None) -> Iterator[None]:
    """Ctrl-C ends the command with the run directory consistent (the last checkpoint is whole) and says how
    to continue."""
    try:
        yield
    except KeyboardInterrupt:
        print(f"\npunch: interrupted; the run directory {out} holds the last checkpoint. "
              f"Continue with: punch {command} --resume {out}", file=sys.stderr)
        raise SystemExit(130) from None


def _eval(args: argparse.Namespace) -> int:
    """`punch eval` and its shortcuts `eval-moving` and `eval-sizes` (their scenario set by the parser)."""
    from punch_trainer.pipelines.evaluation import benchmarks_body, run_eval, scenario_of

    # Before the options' own bounds check: it names size_arms's range and why.
    scenario_of(EvalArgs(policy=args.policy, scenario=args.scenario, arms=getattr(args, "arms", None),
                         scales=getattr(args, "scales", None), proportions=getattr(args, "proportions", None)))
    eval_args = dataclass_from_arguments(EvalArgs, args)
    with backend_for(getattr(args, "ray", None)) as backend:
        out, _ = run_eval(eval_args, backend=backend)
    report = (out / "report.md").read_text()
    print(report)
    print(f"report: {out / 'report.md'}")
    if eval_args.benchmarks:
        from punch_trainer.pipelines.bench import write_section

        body = benchmarks_body(report)
        command = shlex.join(["punch", *args.argv])
        print(f"written to {write_section(eval_args.benchmarks, command, chr(10).join(body).strip())}")
    return 0


def _fig6(args: argparse.Namespace) -> int:
    import shutil

    from punch_trainer.pipelines.bench import write_section
    from punch_trainer.pipelines.experiments import fig6, fig6_table
    from punch_trainer.sim.godot import PROJECT_ROOT

    fig6_args = dataclass_from_arguments(Fig6Args, args)
    out, rows = fig6(fig6_args)
    table = fig6_table(rows)
    print(table)
    if not args.no_write:
        shutil.copy(out / "fig6.png", PROJECT_ROOT / "docs" / "fig6.png")
        command = f"punch experiment fig6 --reward {fig6_args.reward} --seeds {' '.join(map(str, fig6_args.seeds))}"
        note = (f"Reward `{fig6_args.reward}`. A2C runs {fig6_args.a2c_updates} updates of {fig6_args.characters} episodes each. The pretrained "
                f"variants first run the trajectory search ({fig6_args.search_iterations} iterations of 64 rollouts), and their "
                "environment steps, episodes and wall time include it. A2C alone and PPO (Stable-Baselines3, n_steps 128) get "
                "as many environment steps in all as the pretrained variants (matched budgets). 'Mean episode return' averages the sampled (noisy) episodes; the best "
                "noise-free return is the policy's mean actions, evaluated after every update.\n\n![Fig. 6](docs/fig6.png)")
        print(f"written to {write_section('Policy learning (paper Fig. 6)', command, note + chr(10) + chr(10) + table)}")
    print(f"run directory: {out}")
    return 0


def _after_punch(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.experiments import after_punch_headroom

    rows = after_punch_headroom(dataclass_from_arguments(AfterPunchArgs, args))
    print("| start | best return found | share of the last batch that hit |\n|---|---|---|")
    for row in rows:
        print(f"| {row.start} | {row.best_return:.3f} | {100 * row.last_batch_hit_share:.0f}% |")
    return 0


def _style_experiment(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.bench import write_section
    from punch_trainer.pipelines.style_experiment import PLACEMENTS_M, style_experiment

    options = dataclass_from_arguments(StyleExperimentArgs, args)
    rows, table = style_experiment(options)
    hits = ["| style | punches that hit (the reward alone) | median return of the reward alone |", "|---|---|---|",
            *[f"| {row.style} | {row.hits}/{row.punches} | {row.median_return:.3f} |" for row in rows]]
    body = "\n".join([*hits, "", *table])
    print(body)
    if not args.no_write:
        command = (f"punch experiment style --reward {options.reward} --styles {' '.join(options.styles)} "
                   f"--seeds {' '.join(map(str, options.seeds))} --iterations {options.iterations} --rollouts {options.rollouts}")
        note = (f"Reward `{options.reward}`: each style's trajectory search at the same {len(PLACEMENTS_M)} bag placements inside "
                "the shipped policies' reach volume (distance, height, side in m: "
                f"{', '.join(str(p) for p in PLACEMENTS_M)}), each seed, the same budget; the figures are each placement's best "
                "punch (docs/naturalness.md), medians over placements and seeds. docs/style.md says what the style is.")
        print(f"written to {write_section('A motion style', command, note + chr(10) + chr(10) + body)}")
    return 0


def _pretrain(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.pretrain import pretrain_datasets

    result = pretrain_datasets(args.datasets, args.out, dataclass_from_arguments(PretrainArgs, args))
    print(f"pretrained on {result.decisions} decisions from {len(args.datasets)} dataset(s); final actor MSE "
          f"{result.final_actor_mse:.3g}; exported and verified: {result.policy}")
    return 0


def _soup(args: argparse.Namespace) -> int:
    from punch_trainer.learn.soup import soup

    out = soup(args.policies, args.out)
    print(f"averaged the weights of {len(args.policies)} policies; exported and verified: {out}")
    return 0


def _recipe(args: argparse.Namespace) -> int:
    import shutil

    from punch_trainer.pipelines.recipe import RecipeError, load_recipe, run_recipe

    recipe = load_recipe(args.recipe)
    use = {}
    for entry in args.use:
        stage, separator, file = entry.partition("=")
        if not separator:
            raise RecipeError(f"--use takes STAGE=FILE, not {entry!r}")
        use[stage] = Path(file)
    out = args.out or Path("runs") / f"recipe_{recipe.name}"
    with backend_for(args.ray) as backend:
        run_recipe(recipe, out, use=use, until=args.until, dry_run=args.dry_run, backend=backend)
    if args.dry_run or args.until is not None:
        return 0
    print((out / "report.md").read_text())
    if args.install:
        shutil.copyfile(out / "policy.onnx", recipe.policy)
        print(f"installed as {recipe.policy}")
    return 0


def _results(args: argparse.Namespace) -> int:
    import shlex

    from punch_trainer.pipelines.recipe import load_recipe
    from punch_trainer.pipelines.results import measure, shipped_recipes, write_results

    recipes = [load_recipe(path) for path in args.recipes] if args.recipes else shipped_recipes()
    with backend_for(args.ray) as backend:
        reports = measure(recipes, args.out, backend=backend)
    if args.no_write:
        print(f"reports in {args.out}")
        return 0
    for path in write_results(recipes, reports, shlex.join(["punch", *args.argv])):
        print(f"written: {path}")
    return 0


def _replay(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.replay import run_replay

    out, rows = run_replay(dataclass_from_arguments(ReplayArgs, args))
    print((out / "report.md").read_text())
    print(f"report: {out / 'report.md'}")
    return 0


def _render(args: argparse.Namespace) -> int:
    from punch_trainer.pipelines.render import render

    out = render(dataclass_from_arguments(RenderArgs, args))
    print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="punch", description="Train and run physics-based punching policies.")
    parser.add_argument("--version", action="version", version=f"punch {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the full traceback of an error, not only its message")
    commands = parser.add_subparsers(dest="command", required=True)

    selfcheck = commands.add_parser("selfcheck", help="check Godot, Jolt, the extension and ONNX Runtime end to end")
    add_dataclass_arguments(selfcheck, SelfCheckArgs)
    selfcheck.set_defaults(run=_selfcheck)

    search = commands.add_parser("search", help="trajectory search (TTR) for a reward; writes a run directory")
    add_dataclass_arguments(search, SearchArgs, exclude=["decision_period"])
    search.set_defaults(reward=None)  # to tell a --reward given with --resume; _run_args fills the default in
    search.add_argument("--resume", type=Path, metavar="RUN_DIR",
                        help="continue an interrupted search from its checkpoint, with its own arguments (other options are ignored; "
                             "a reward that is a file must be named again with --reward)")
    add_ray_option(search)
    search.set_defaults(run=_search)

    train = commands.add_parser("train", help="search, pretraining, A2C and ONNX export for a reward")
    add_dataclass_arguments(train, TrainArgs, default_notes=reach_default_notes())
    train.set_defaults(reward=None)  # to tell a --reward given with --resume; _run_args fills the default in
    train.add_argument("--resume", type=Path, metavar="RUN_DIR",
                       help="continue an interrupted run from its checkpoints, with its own arguments (other options are ignored; "
                            "a reward that is a file must be named again with --reward)")
    add_ray_option(train)
    train.set_defaults(run=_train)

    pre = commands.add_parser("pretrain", help="pretrain a policy on one or several trajectory datasets (no simulation)")
    pre.add_argument("datasets", type=Path, nargs="+", help="dataset.npz files written by punch search")
    pre.add_argument("--out", type=Path, default=Path("pretrained.onnx"), help="the policy file to write (default: pretrained.onnx)")
    add_dataclass_arguments(pre, PretrainArgs)
    pre.set_defaults(run=_pretrain)

    soup = commands.add_parser("soup", help="one policy whose weights are the mean of several fine-tuned from one parent "
                                            "(a weight-space ensemble; experiments/notebook.md)")
    soup.add_argument("policies", type=Path, nargs="+", help="policy files of one lineage (one contract, reward, noise "
                                                             "scale and observation normalisation)")
    soup.add_argument("--out", type=Path, required=True, help="the policy file to write")
    soup.set_defaults(run=_soup)

    recipe = commands.add_parser("recipe", help="make a shipped policy again from its recipe (recipes/*.toml): every "
                                 "training stage and soup, in order, resumable")
    recipe.add_argument("recipe", type=Path, help="the recipe file, e.g. recipes/straight.toml")
    recipe.add_argument("--out", type=Path, help="the run directory, one folder a stage (default runs/recipe_<name>); "
                                                 "stages already made there with the same options are kept")
    recipe.add_argument("--dry-run", action="store_true", help="print each stage's command, run nothing")
    recipe.add_argument("--until", metavar="STAGE", help="stop after this stage")
    recipe.add_argument("--use", action="append", default=[], metavar="STAGE=FILE",
                        help="take FILE as that stage's policy instead of making it (a stage made before); repeatable")
    recipe.add_argument("--install", action="store_true", help="copy the policy over the file the recipe names "
                                                               "(the addon's policies/)")
    add_ray_option(recipe)
    recipe.set_defaults(run=_recipe)

    results = commands.add_parser("results", help="measure every shipped policy with the evaluator and write the figures the "
                                  "docs show (BENCHMARKS.md, the policies' README)")
    results.add_argument("recipes", type=Path, nargs="*", help="the recipes whose policies to measure (default: every "
                                                               "recipe in recipes/)")
    results.add_argument("--out", type=Path, default=Path("runs") / "results", help="where the reports and plots go "
                                                                                    "(default runs/results)")
    results.add_argument("--no-write", action="store_true", help="measure only; leave BENCHMARKS.md and the README alone")
    add_ray_option(results)
    results.set_defaults(run=_results)

    evaluation = commands.add_parser("eval", help="success of a policy in an evaluation scenario (held-out placements, noise, "
                                                  "moving bodies and targets, arm sizes; docs/evaluation.md), through "
                                                  "PunchController in Godot")
    eval_parsers = {"sigmas": parse_sigmas, "arms": parse_sizes, "scales": parse_scales, "proportions": parse_sizes}
    add_dataclass_arguments(evaluation, EvalArgs, exclude=["timeout_s"], value_parsers=eval_parsers)
    add_ray_option(evaluation)
    evaluation.set_defaults(run=_eval)

    moving = commands.add_parser("eval-moving", help="punch eval --scenario moving: hit rates of a policy while its character "
                                                     "walks, turns and steps in, and against a moving target")
    add_dataclass_arguments(moving, EvalArgs, value_parsers=eval_parsers,
                            exclude=["scenario", "conditions", "scales", "proportions", "noisy_episodes", "search_iterations", "timeout_s"])
    moving.add_argument("--cases", dest="conditions", nargs="+", metavar="CASE",
                        help="motion cases to run, by name (default: all; docs/moving.md lists them)")
    moving.set_defaults(run=_eval, scenario="moving")

    sizes = commands.add_parser("eval-sizes", help="punch eval --scenario sizes: hit rates of a policy when its character's "
                                                   "arms are sized to other bodies (PunchCharacter.size_arms)")
    add_dataclass_arguments(sizes, EvalArgs, value_parsers=eval_parsers,
                            exclude=["scenario", "conditions", "arms", "lead_s", "noisy_episodes", "search_iterations", "timeout_s"])
    sizes.set_defaults(run=_eval, scenario="sizes")

    replay = commands.add_parser("replay", help="replay a policy through PunchController in Godot at several noise sigmas (paper Fig. 10-11)")
    # bags and start are punch eval's conditions, not options of a replay
    add_dataclass_arguments(replay, ReplayArgs, exclude=["bags", "start", "timeout_s"], value_parsers={"sigmas": parse_sigmas})
    replay.set_defaults(run=_replay)

    render = commands.add_parser("render", help="a GIF of a policy's punches at one or several sigmas (Godot Movie Maker under Xvfb)")
    add_dataclass_arguments(render, RenderArgs, value_parsers={"sigmas": parse_sigmas, "bags": parse_bags})
    render.set_defaults(run=_render)

    experiment = commands.add_parser("experiment", help="experiments of the paper")
    experiments = experiment.add_subparsers(dest="experiment", required=True)
    fig6 = experiments.add_parser("fig6", help="A2C only, A2C after pretraining, and SB3 PPO (paper Fig. 6)")
    add_dataclass_arguments(fig6, Fig6Args)
    add_no_write_option(fig6)
    fig6.set_defaults(run=_fig6)
    after = experiments.add_parser("after-punch", help="what a punch from the end of an earlier one can score")
    after.add_argument("dataset", type=Path, help=field_docs(AfterPunchArgs)["dataset"])
    add_dataclass_arguments(after, AfterPunchArgs, exclude=["dataset"])
    after.set_defaults(run=_after_punch)
    style = experiments.add_parser("style", help="the motion style's effect on the search's punches (docs/style.md)")
    add_dataclass_arguments(style, StyleExperimentArgs)
    add_no_write_option(style)
    style.set_defaults(run=_style_experiment)

    bench = commands.add_parser("bench", help="measure speed and write BENCHMARKS.md")
    bench_targets = bench.add_subparsers(dest="target", required=True)
    env = bench_targets.add_parser("env", help="simulation throughput in character-frames per second")
    add_dataclass_arguments(env, BenchEnvArgs)
    add_no_write_option(env)
    add_ray_option(env)
    env.set_defaults(run=_bench_env)
    inference = bench_targets.add_parser("inference", help="PunchController inference and per-frame cost in Godot, 1 to 256 controllers")
    add_dataclass_arguments(inference, BenchInferenceArgs, default_notes={"policy": "the demo's straight punch"})
    add_no_write_option(inference)
    inference.set_defaults(run=_bench_inference)
    search_bench = bench_targets.add_parser("search", help="TTR against CEM and CMA-ES at equal rollouts")
    add_dataclass_arguments(search_bench, BenchSearchArgs)
    add_no_write_option(search_bench)
    search_bench.set_defaults(run=_bench_search)
    soak = bench_targets.add_parser("soak", help="pairs trading punches, blocks and hits for minutes: promises, memory, frame cost")
    add_dataclass_arguments(soak, BenchSoakArgs)
    add_no_write_option(soak)
    soak.set_defaults(run=_bench_soak)
    return parser


def add_no_write_option(command: argparse.ArgumentParser) -> None:
    command.add_argument("--no-write", action="store_true", help="print only; leave BENCHMARKS.md alone")


def add_ray_option(command: argparse.ArgumentParser) -> None:
    command.add_argument("--ray", nargs="?", const="auto", metavar="ADDRESS",
                         help="run the Godot workers as Ray actors on the cluster at ADDRESS (alone, or 'auto': the one "
                              "RAY_ADDRESS names or `ray start` began on this machine; 'simulated[:N]': N nodes simulated on "
                              "this machine, to try it); docs/cluster.md")


def _interrupt(signum: int, _frame: object) -> None:
    """SIGTERM and SIGHUP end a command as Ctrl-C does: every `with` unwinds, so temporary folders are removed,
    Godot is stopped and a run directory is left with its last whole checkpoint."""
    raise KeyboardInterrupt(signal.Signals(signum).name)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the command as given, for the results it writes
    if threading.current_thread() is threading.main_thread():
        for number in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(number, _interrupt)
    try:
        return int(args.run(args))
    except KeyboardInterrupt as interrupt:
        if args.debug:
            raise
        print(f"punch: interrupted{f' ({interrupt})' if str(interrupt) else ''}", file=sys.stderr)
        return 130
    except PunchError as error:
        if args.debug:
            raise
        print(f"punch: {error}", file=sys.stderr)
        return 1
    except OSError as error:  # a read-only or full disk, a missing file: the user's to fix, not a bug
        if args.debug:
            raise
        where = f": {error.filename}" if error.filename else ""
        print(f"punch: {error.strerror or error}{where} (run with --debug for the traceback)", file=sys.stderr)
        return 1
    except ValueError as error:  # malformed input the checks above did not name (a file's garbage metadata)
        if args.debug:
            raise
        print(f"punch: invalid input: {type(error).__name__}: {error} (run with --debug for the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
