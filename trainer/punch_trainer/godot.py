"""Starting Godot: every Godot process of the trainer and the tests goes through tools/godot, which picks
the user's Godot ($GODOT, or `godot` on PATH when >= 4.6) or the project's private copy."""

from __future__ import annotations

import os
import subprocess
from dataclasses import dataclass
from pathlib import Path

from punch_trainer.errors import GodotNotFoundError, GodotRunError

PROJECT_ROOT = Path(__file__).resolve().parents[2]
GODOT_WRAPPER = PROJECT_ROOT / "tools" / "godot"
GODOT_PROJECT = PROJECT_ROOT / "godot_project"

# Lines in Godot's log that mean a run failed even if the process exited 0 (the same checks as
# godot-rust's own integration-test runner).
FATAL_LOG_PATTERNS = (
    "SCRIPT ERROR:",
    "Parse Error:",
    "Can't open dynamic library",
    "GDExtension dynamic library not found",
    "Error loading extension",
    "ObjectDB instances leaked at exit",
    "resources still in use at exit",
    "panicked at",
)


@dataclass(frozen=True)
class GodotRun:
    """A finished Godot process: its exit code and its combined stdout and stderr."""

    returncode: int
    log: str

    def fatal_lines(self) -> list[str]:
        """Lines of the log that match a fatal pattern."""
        return [line for line in self.log.splitlines() if any(p in line for p in FATAL_LOG_PATTERNS)]


def godot_command() -> list[str]:
    """The command that starts Godot (the wrapper; it resolves which Godot at each start)."""
    if not os.access(GODOT_WRAPPER, os.X_OK):
        raise GodotNotFoundError(f"{GODOT_WRAPPER} is missing or not executable; is this a checkout of the project?")
    return [str(GODOT_WRAPPER)]


def run_godot(
    args: list[str],
    *,
    timeout_s: float = 120.0,
    check: bool = True,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
) -> GodotRun:
    """Runs Godot headless-or-not as `args` say, waits, and returns the run. With `check`, raises
    GodotRunError when the exit code is non-zero, the run times out, or the log has a fatal line."""
    command = godot_command() + args
    try:
        completed = subprocess.run(
            command,
            cwd=cwd or PROJECT_ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            text=True,
            errors="replace",
            timeout=timeout_s,
        )
    except subprocess.TimeoutExpired as error:
        log = error.stdout if isinstance(error.stdout, str) else (error.stdout or b"").decode(errors="replace")
        raise GodotRunError(f"Godot did not finish within {timeout_s:.0f} s: {' '.join(args)}", log) from None
    run = GodotRun(completed.returncode, completed.stdout)
    if completed.returncode == 3 and run.log.startswith("error:"):  # tools/godot found no usable Godot
        raise GodotNotFoundError(run.log.strip())
    if check:
        fatal = run.fatal_lines()
        if completed.returncode != 0 or fatal:
            reason = f"exit code {completed.returncode}" if completed.returncode != 0 else f"fatal log line: {fatal[0]}"
            raise GodotRunError(f"Godot run failed ({reason}): {' '.join(args)}\n{tail(run.log)}", run.log)
    return run


def tail(text: str, lines: int = 30) -> str:
    """The last `lines` lines of a log, for error messages."""
    return "\n".join(text.splitlines()[-lines:])
