"""Starting Godot, in one way: every Godot process of the trainer and the tests is started by `start_godot`,
through tools/godot (which picks the user's Godot: $GODOT, or `godot` on PATH when >= 4.6, or the project's
private copy), in a process group of its own, and dies with the trainer even when the trainer is killed."""

from __future__ import annotations

import contextlib
import ctypes
import os
import selectors
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from punch_trainer.errors import GodotNotFoundError, GodotRunError, PunchError

PROJECT_ROOT = Path(__file__).resolve().parents[3]
GODOT_WRAPPER = PROJECT_ROOT / "tools" / "godot"
GODOT_PROJECT = PROJECT_ROOT / "godot_project"
# The default policies the addon ships (one per style), which the demo plays too.
ADDON_POLICIES = PROJECT_ROOT / "addons" / "punch_controller" / "policies"

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


def start_godot(args: list[str], *, cwd: Path | None = None, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    """Starts Godot with `args`; its stdout and stderr come together, as text, from `.stdout`. The process
    (and whatever it starts) is in a new session, so `stop_godot` ends all of it, and Linux kills it when
    this process dies, by any signal."""
    return subprocess.Popen(godot_command() + args, cwd=cwd or PROJECT_ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True, errors="replace",
                            start_new_session=True, preexec_fn=_die_with_parent if sys.platform == "linux" else None)


def stop_godot(process: subprocess.Popen[str], grace_s: float = 5.0, *, close_output: bool = True) -> None:
    """Ends a Godot started by `start_godot`, with everything in its process group: SIGTERM, then SIGKILL
    after `grace_s`; then closes its output unless `close_output` is False (a reader thread of its own
    closes it). Idempotent."""
    if process.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=grace_s)
    if process.stdout and close_output:
        process.stdout.close()


def _die_with_parent() -> None:
    """Runs in the Godot child before exec: Linux kills it when the trainer dies, even by SIGKILL, so a crashed
    trainer leaves no simulator behind (PR_SET_PDEATHSIG survives the exec of tools/godot and Godot)."""
    pr_set_pdeathsig = 1
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL)


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
    process = start_godot(args, cwd=cwd, env=env)
    try:
        log, _ = process.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        log, _ = process.communicate()
        raise GodotRunError(f"Godot did not finish within {timeout_s:.0f} s: {' '.join(args)}", log) from None
    finally:
        stop_godot(process)
    run = GodotRun(process.returncode, log)
    if process.returncode == 3 and run.log.startswith("error:"):  # tools/godot found no usable Godot
        raise GodotNotFoundError(run.log.strip())
    if check:
        fatal = run.fatal_lines()
        if process.returncode != 0 or fatal:
            reason = f"exit code {process.returncode}" if process.returncode != 0 else f"fatal log line: {fatal[0]}"
            raise GodotRunError(f"Godot run failed ({reason}): {' '.join(args)}\n{tail(run.log)}", run.log)
    return run


def run_godot_tool(script: str, options: dict[str, object], *, what: str, timeout_s: float,
                   on_progress: Callable[[int], None] | None = None,
                   timeout_error: Callable[[str], PunchError] = GodotRunError) -> str:
    """Runs one of godot_project/tools' measuring scripts headless at 120 Hz (`script`: its name, as
    `evaluate`), passing `options` as `--name=value`, and returns its log. The script reports progress with
    lines `<NAME>_PROGRESS done total` (`on_progress` gets `done`), ends with a line `<NAME>_DONE`, where NAME is
    the script's first word in capitals (`EVALUATE` for `evaluate`), and says what went wrong in a line
    `error: <script>: ...`. The deadline is kept by the clock, not by Godot's output: a Godot that hangs silently
    is stopped too, with `timeout_error`; a non-zero exit, a fatal or error line, or no DONE line raise
    GodotRunError, naming `what` ("the moving punches") and the log's tail."""
    name = script.split("_")[0].upper()
    command = ["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", f"res://tools/{script}.gd",
               "--", *(f"--{key}={value}" for key, value in options.items())]
    log: list[str] = []
    deadline = time.monotonic() + timeout_s
    process = start_godot(command)
    assert process.stdout is not None
    selector = selectors.DefaultSelector()
    selector.register(process.stdout, selectors.EVENT_READ)
    try:
        while True:
            left_s = deadline - time.monotonic()
            if left_s <= 0 or not selector.select(timeout=left_s):
                raise timeout_error(f"{what} did not finish within {timeout_s:.0f} s (Godot was stopped):\n{tail(''.join(log))}")
            line = process.stdout.readline()
            if not line:
                break
            log.append(line)
            if line.startswith(f"{name}_PROGRESS ") and on_progress is not None:
                on_progress(int(line.split()[1]))
        process.wait(timeout=60)
    finally:
        selector.close()
        stop_godot(process)
    text = "".join(log)
    if process.returncode == 3 and text.startswith("error:"):  # tools/godot found no usable Godot
        raise GodotNotFoundError(text.strip())
    fatal = [line for line in log if any(p in line for p in FATAL_LOG_PATTERNS) or line.startswith(f"error: {script}")]
    if process.returncode != 0 or fatal or f"{name}_DONE" not in text:
        raise GodotRunError(f"{what} failed in Godot (exit code {process.returncode}):\n{tail(text)}", text)
    return text


def tail(text: str, lines: int = 30) -> str:
    """The last `lines` lines of a log, for error messages."""
    return "\n".join(text.splitlines()[-lines:])
