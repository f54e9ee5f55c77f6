"""Shared pytest setup. Two markers select tests (`./dev test fast` runs `-m "not godot and not expensive"`):
- `godot`: the test starts a real Godot through tools/godot (the README's test command, ./dev check, sets it
  up first). The marker checks itself: every Godot start of the tests goes through a recording stand-in for
  $GODOT, and a test that starts Godot without the marker fails, naming what it started.
- `expensive`: the test runs for minutes: a training pipeline (a trajectory search, pretraining, A2C or
  `punch train`), or the core's test suite built for Windows and run under Wine."""

import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from punch_trainer.errors import GodotNotFoundError
from punch_trainer.sim.godot import run_godot

PROJECT_ROOT = Path(__file__).resolve().parents[2]
FIXTURES = PROJECT_ROOT / "tests" / "fixtures"
sys.path.insert(0, str(FIXTURES))  # the test characters' maker, `characters` (a fixture, not the trainer's)

GODOT_STARTS_VARIABLE = "PUNCH_TEST_GODOT_STARTS"
"""names the file where the recording stand-in for $GODOT writes one line per Godot it starts"""
RECORDING_GODOT = """#!/bin/sh
# Stands in for $GODOT during the tests: writes one line per Godot start into ${starts}, then starts Godot
# the way tools/godot does without it. tools/godot's own version probe (run under `timeout`) is no start.
if [ "$(cat /proc/$PPID/comm 2>/dev/null)" != timeout ]; then
    echo "$*" >> '${starts}'
fi
if [ -n "$PUNCH_TEST_USER_GODOT" ]; then GODOT="$PUNCH_TEST_USER_GODOT"; export GODOT; else unset GODOT; fi
exec "${wrapper}" "$@"
"""
GODOT_STARTS_BEFORE = pytest.StashKey[int]()


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "godot: starts a real headless Godot (Jolt) with the built extension")
    config.addinivalue_line("markers", "expensive: runs for minutes (a training pipeline: search, pretraining, A2C, punch train)")
    record_godot_starts()


def record_godot_starts() -> None:
    """Points $GODOT, for this process and every process it starts, at the recording stand-in (where there is
    a Godot to stand in for: elsewhere the tests that start one fail with tools/godot's own message)."""
    try:
        run_godot(["--which"])  # tools/godot says which Godot it would start, and starts none
    except GodotNotFoundError:
        return
    folder = Path(tempfile.mkdtemp(prefix="punch-godot-starts-"))
    starts, stand_in = folder / "starts.log", folder / "godot"
    starts.touch()
    stand_in.write_text(RECORDING_GODOT.replace("${starts}", str(starts)).replace("${wrapper}", str(PROJECT_ROOT / "tools" / "godot")))
    stand_in.chmod(0o755)
    os.environ["PUNCH_TEST_USER_GODOT"] = os.environ.get("GODOT", "")
    os.environ["GODOT"], os.environ[GODOT_STARTS_VARIABLE] = str(stand_in), str(starts)


def pytest_unconfigure(config: pytest.Config) -> None:
    if GODOT_STARTS_VARIABLE in os.environ:
        shutil.rmtree(Path(os.environ[GODOT_STARTS_VARIABLE]).parent, ignore_errors=True)


def godot_starts() -> list[str]:
    """The command lines of the Godot processes started so far in this session, oldest first."""
    if GODOT_STARTS_VARIABLE not in os.environ:
        return []
    return Path(os.environ[GODOT_STARTS_VARIABLE]).read_text().splitlines()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    item.stash[GODOT_STARTS_BEFORE] = len(godot_starts())


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]):
    """Fails a passing test that started Godot (in its fixtures or its body) without the `godot` marker."""
    outcome = yield
    report = outcome.get_result()
    if call.when != "call" or not report.passed or item.get_closest_marker("godot") is not None:
        return
    started = godot_starts()[item.stash.get(GODOT_STARTS_BEFORE, 0):]
    if started:
        report.outcome = "failed"
        report.longrepr = (f"{item.nodeid} started {len(started)} Godot process(es) but is not marked `godot` "
                           f"(@pytest.mark.godot); the first: godot {started[0]}")


def processes_whose_command(matches: Callable[[list[bytes]], bool]) -> set[int]:
    """PIDs of the processes on this machine whose command line (its arguments) `matches`."""
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if matches(command):
            found.add(int(entry.name))
    return found


def godot_processes() -> set[int]:
    """PIDs of the Godot processes running this project: a program named godot* (Godot itself, or tools/godot
    about to become it) whose command line names this checkout. A build of punch_godot is not one."""
    return processes_whose_command(lambda command: any(part.rsplit(b"/", 1)[-1].lower().startswith(b"godot") for part in command)
                                   and any(str(PROJECT_ROOT).encode() in part for part in command))


RAY_MARKS = (b"ray::", b"/ray/core/src/ray/", b"ray/_private/", b"ray/dashboard/", b"ray/autoscaler/")


def ray_processes() -> set[int]:
    """PIDs of Ray's own processes (GCS, raylets, workers, agents) on this machine."""
    return processes_whose_command(lambda command: any(mark in part for part in command for mark in RAY_MARKS))


@pytest.fixture(scope="session", autouse=True)
def no_godot_left_behind():
    """After the whole suite, no Godot or Ray process it started may still run (counted in the process table)."""
    before, ray_before = godot_processes(), ray_processes()
    yield
    deadline = time.monotonic() + 10
    while ((left := godot_processes() - before) or ray_processes() - ray_before) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not left, f"Godot processes left behind by the tests: {sorted(left)}"
    assert not ray_processes() - ray_before, f"Ray processes left behind by the tests: {sorted(ray_processes() - ray_before)}"
    print(f"\nprocess check: {len(before)} Godot process(es) of this project before the tests, {len(godot_processes())} after")
