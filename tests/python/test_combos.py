"""Combos as games send them: random streams of `punch()`, `combo()`, `cancel()` and `recover()` calls, at random
frames and inside the controller's own signal handlers, on 16 characters with the addon's moveset. Every punch has
one `punch_finished`, every string one `combo_finished` after its last punch, and every queued move starts once, in
order, unless a later call dropped it (tests/godot/combo_streams.gd checks each signal as it comes)."""

import json

import pytest

from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot


@pytest.mark.parametrize("seed", [1, 2])
def test_random_command_streams_keep_every_combo_promise(seed):
    script = PROJECT_ROOT / "tests" / "godot" / "combo_streams.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--",
                     f"--seed={seed}", "--frames=2400"], check=False, timeout_s=300)
    line = next((line for line in run.log.splitlines() if line.startswith("COMBO_STREAMS ")), None)
    assert line is not None and run.fatal_lines() == [] and "ERROR" not in run.log, run.log[-3000:]
    report = json.loads(line[len("COMBO_STREAMS "):])
    assert report["problem_count"] == 0, report["problems"]
    streams = report["streams"]
    assert all(s["started"] == s["finished"] and s["strings"] == s["combos_finished"] for s in streams), streams
    # The streams did what they are for: many calls, some inside handlers, many punches chained from the queue.
    assert report["calls"] > 1000 and report["handler_calls"] > 100, report
    assert sum(s["chained_starts"] for s in streams) > 300, streams


def test_a_combinations_next_punch_starts_as_near_its_guard_as_its_move_asks():
    """`PunchMoveset`'s "Returns to guard": the uppercuts start from a settled guard by default, the other moves from
    near it (0.1 rad); a wider tolerance starts the uppercut after a cross sooner (tests/godot/guard_tolerance.gd)."""
    script = PROJECT_ROOT / "tests" / "godot" / "guard_tolerance.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script)],
                    check=False, timeout_s=120)
    line = next((line for line in run.log.splitlines() if line.startswith("GUARD_TOLERANCE ")), None)
    assert line is not None and run.fatal_lines() == [] and "ERROR" not in run.log, run.log[-3000:]
    report = json.loads(line[len("GUARD_TOLERANCE "):])
    defaults = report["defaults"]
    assert defaults["lead_uppercut"] == defaults["rear_uppercut"] == pytest.approx(0.02)
    assert all(defaults[move] == pytest.approx(0.1) for move in ("jab", "cross", "lead_hook", "rear_hook")), defaults

    def uppercut_startup_frames(case):
        started = dict(report[case]["started"])["lead_uppercut"]
        left_hits = [frame for hand, frame in report[case]["hits"] if hand == "left"]
        assert report[case]["finished"] == ["landed", "landed"] and left_hits, report[case]
        return left_hits[0] - started

    assert uppercut_startup_frames("wide") + 10 < uppercut_startup_frames("default"), report
