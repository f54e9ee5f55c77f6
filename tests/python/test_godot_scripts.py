"""Runs every headless Godot test script in tests/godot inside godot_project. A script fails the test by
exiting non-zero, and so does any fatal line in Godot's log (SCRIPT ERROR, a library that failed to load,
objects leaked at exit)."""

from pathlib import Path

import pytest

from punch_trainer.sim.godot import GODOT_PROJECT, run_godot

GODOT_TESTS = sorted((Path(__file__).resolve().parents[1] / "godot").glob("test_*.gd"))


@pytest.mark.godot
@pytest.mark.parametrize("script", GODOT_TESTS, ids=[s.stem for s in GODOT_TESTS])
def test_godot_script(script: Path) -> None:
    run = run_godot(["--headless", "--path", str(GODOT_PROJECT), "--script", str(script)], check=False)
    assert run.returncode == 0, run.log
    assert run.fatal_lines() == [], run.log


def test_there_are_godot_tests() -> None:
    assert GODOT_TESTS, "tests/godot has no test_*.gd scripts"
