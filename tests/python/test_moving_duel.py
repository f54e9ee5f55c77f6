"""The moving duel demo (godot_project/demo/moving_duel.tscn): two characters moved by their CharacterBody3D every
physics frame circle each other and trade punches, the simulated bodies carried along."""

import json

import pytest

from punch_trainer.sim.godot import GODOT_PROJECT, run_godot

pytestmark = pytest.mark.godot


def test_the_moving_duel_circles_turns_and_lands_punches_on_both_sides():
    """Ten seconds with both sides on the autopilot: each mover walks and turns (and the simulated pelvis with
    it, read from the physics server), each side punches only with the opponent in reach, and each strikes the other (its trunk or its guard)."""
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "res://demo/moving_duel.tscn",
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
