"""The `punch` command."""

from __future__ import annotations

import argparse
import sys

from punch_trainer import __version__
from punch_trainer.errors import PunchError


def _selfcheck(args: argparse.Namespace) -> int:
    from punch_trainer.selfcheck import run_selfcheck

    report = run_selfcheck(batch=args.batch, seed=args.seed)
    print("\n".join(report.lines()))
    print("Self-check passed.")
    return 0


def _bench_env(args: argparse.Namespace) -> int:
    from punch_trainer.bench import bench_env, env_table, write_section

    results = bench_env(characters=args.characters, processes=args.processes, frames=args.frames, episodes=args.episodes)
    table = env_table(results)
    print(table)
    if not args.no_write:
        command = "punch bench env" + ("" if args.characters == [1, 16, 64] and args.processes == [1, 2] else
                                       f" --characters {' '.join(map(str, args.characters))} --processes {' '.join(map(str, args.processes))}")
        note = ("Character-physics-frames per second through the real TCP socket, reset included, "
                f"{args.frames}-frame episodes at 120 Hz. Open loop: one `rollout` message per episode; "
                "closed loop: `reset` then one `step` per decision.")
        print(f"written to {write_section('Env throughput', command, note + chr(10) + chr(10) + table)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="punch", description="Train and run physics-based punching policies.")
    parser.add_argument("--version", action="version", version=f"punch {__version__}")
    commands = parser.add_subparsers(dest="command", required=True)

    selfcheck = commands.add_parser("selfcheck", help="check Godot, Jolt, the extension and ONNX Runtime end to end")
    selfcheck.add_argument("--batch", type=int, default=8, help="rows of the test input batch")
    selfcheck.add_argument("--seed", type=int, default=0, help="seed of the test model and input")
    selfcheck.set_defaults(run=_selfcheck)

    bench = commands.add_parser("bench", help="measure speed and write BENCHMARKS.md")
    bench_targets = bench.add_subparsers(dest="target", required=True)
    env = bench_targets.add_parser("env", help="simulation throughput in character-frames per second")
    env.add_argument("--characters", type=int, nargs="+", default=[1, 16, 64], help="characters per process (N)")
    env.add_argument("--processes", type=int, nargs="+", default=[1, 2], help="Godot processes (K)")
    env.add_argument("--frames", type=int, default=50, help="physics frames per episode")
    env.add_argument("--episodes", type=int, default=6, help="episodes measured per configuration")
    env.add_argument("--no-write", action="store_true", help="print only; leave BENCHMARKS.md alone")
    env.set_defaults(run=_bench_env)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except PunchError as error:
        print(f"punch: {error}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
