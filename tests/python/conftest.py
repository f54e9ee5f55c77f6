"""Shared pytest setup. Tests marked `godot` start the real headless Godot through tools/godot; the
README's test command (./dev check) sets it up first."""

import time
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[2]
FIXTURES = PROJECT_ROOT / "tests" / "fixtures"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "godot: starts a real headless Godot (Jolt) with the built extension")


def godot_processes() -> set[int]:
    """PIDs of the Godot processes running this project (their command line names its Godot project)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if any(b"godot" in part for part in command) and any(str(PROJECT_ROOT).encode() in part for part in command):
            found.add(int(entry.name))
    return found


def ray_processes() -> set[int]:
    """PIDs of Ray's own processes (GCS, raylets, workers, agents) on this machine."""
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ")
        except OSError:
            continue
        if any(mark in command for mark in (b"ray::", b"/ray/core/src/ray/", b"ray/_private/", b"ray/dashboard/", b"ray/autoscaler/")):
            found.add(int(entry.name))
    return found


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
