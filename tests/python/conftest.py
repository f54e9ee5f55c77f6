"""Shared pytest setup. Tests marked `godot` start the real headless Godot through tools/godot; the
README's test command (./dev check) sets it up first."""

import time
from collections.abc import Callable
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[2]
FIXTURES = PROJECT_ROOT / "tests" / "fixtures"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "godot: starts a real headless Godot (Jolt) with the built extension")


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
    """PIDs of the Godot processes running this project (their command line names its Godot project)."""
    return processes_whose_command(lambda command: any(b"godot" in part for part in command)
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
