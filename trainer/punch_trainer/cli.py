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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="punch", description="Train and run physics-based punching policies.")
    parser.add_argument("--version", action="version", version=f"punch {__version__}")
    commands = parser.add_subparsers(dest="command", required=True)

    selfcheck = commands.add_parser("selfcheck", help="check Godot, Jolt, the extension and ONNX Runtime end to end")
    selfcheck.add_argument("--batch", type=int, default=8, help="rows of the test input batch")
    selfcheck.add_argument("--seed", type=int, default=0, help="seed of the test model and input")
    selfcheck.set_defaults(run=_selfcheck)
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
