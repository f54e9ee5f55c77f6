"""The moving duel demo (godot_project/demo/moving_duel.tscn): two characters moved by their CharacterBody3D every
physics frame circle each other and trade punches, the simulated bodies carried along."""

import json

import pytest

from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot


def test_the_moving_duel_circles_turns_and_lands_punches_on_both_sides():
    """Ten seconds with both sides on the autopilot: each mover walks and turns (and the simulated pelvis with
    it, read from the physics server), each side punches only with the opponent in reach, and each strikes the other (its trunk or its guard)."""
    script = PROJECT_ROOT / "tests" / "godot" / "moving_duel_run.gd"  # the demo measured from outside it
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script),
                     "--", "--autoplay", "--seconds=10"], check=False, timeout_s=300)
    assert "ERROR" not in run.log and run.fatal_lines() == [], run.log[-3000:]
    line = next((line for line in run.log.splitlines() if line.startswith("MOVING_DUEL ")), None)
    assert line is not None, run.log[-3000:]
    report = json.loads(line.removeprefix("MOVING_DUEL "))
    print(report)
    assert sorted(report["policies"]) == ["hook", "straight", "swing"], report
    for name, side in report["sides"].items():
        assert side["path_m"] > 1.0 and side["pelvis_path_m"] > 0.9 * side["path_m"], (name, side)
        assert side["turned_rad"] > 1.0 and side["pelvis_turned_rad"] > 0.9 * side["turned_rad"], (name, side)
        assert side["punches"] >= 2 and side["out_of_reach"] == 0, (name, side)
        assert side["hits"] >= 1, (name, side)


def test_the_moving_duel_is_played_from_the_keyboard():
    """Key events as the OS sends them: the first takes your side from the autopilot; W walks you in, Space
    punches (the straight), 2 picks the hook, D circles the opponent while you punch again, S backs off; you
    keep facing the opponent."""
    script = PROJECT_ROOT / "tests" / "godot" / "moving_duel_keys.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script)],
                    check=False, timeout_s=120)
    assert "ERROR" not in run.log and run.fatal_lines() == [], run.log[-3000:]
    line = next((line for line in run.log.splitlines() if line.startswith("MOVING_DUEL_KEYS ")), None)
    assert line is not None, run.log[-3000:]
    report = json.loads(line.removeprefix("MOVING_DUEL_KEYS "))
    print(report)
    assert report["driver_before"] == "auto" and report["driver_after"] == "keys", report
    assert report["closed_m"] > 0.0 and report["backed_m"] > 0.2, report
    assert report["punches"] == [True, True] and report["styles"] == ["straight", "hook"], report
    assert abs(report["circled_rad"]) > 0.5 and report["facing_error_rad"] < 0.1, report
