"""Blocking (`PunchController.block()`): a block raises a high guard with both fists in front of the face, holds it
for its time or until stopped, then goes back to guard without a `recovered`; a punch ends it; a bad time is refused
(tests/godot/blocking.gd). Measured with the one evaluator's `blocks` scenario: a jab or a cross of the shipped
policies at the head of a second character, which blocks or stands in guard."""

import json
import math

import pytest

from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot


def test_a_block_raises_both_fists_before_the_face_for_its_time_and_a_punch_ends_it():
    script = PROJECT_ROOT / "tests" / "godot" / "blocking.gd"
    run = run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script)],
                    check=False, timeout_s=120)
    line = next((line for line in run.log.splitlines() if line.startswith("BLOCKING ")), None)
    assert line is not None and run.fatal_lines() == [], run.log[-3000:]
    assert run.log.count("ERROR:") == 2 and "block(NaN): the seconds must be a number" in run.log, run.log[-3000:]
    assert "knocked down: it blocks once recover()" in run.log, run.log[-3000:]
    report = json.loads(line[len("BLOCKING "):])
    samples = report["samples"]
    assert report["blocked"] and samples["blocking"]["blocking"] and samples["held"]["blocking"], samples
    for label in ("blocking", "held"):
        head = samples[label]["head"]
        for fist in samples[label]["fists"]:
            # In front of the face, beside the centre line, level with the head (the guard holds them at the chin).
            assert 0.15 < fist[2] - head[2] < 0.30 and abs(fist[0]) < 0.12 and abs(fist[1] - head[1]) < 0.06, samples[label]
    # A head 6 cm higher on its neck (an own rig's, `size_head`): the gloves rise with it, as far before the face.
    assert report["head_sized"], report
    tall, square = samples["tall_headed_blocking"], samples["blocking"]
    assert tall["head"][1] == pytest.approx(square["head"][1] + 0.06, abs=0.01), (tall, square)
    for fist, square_fist in zip(tall["fists"], square["fists"], strict=True):
        assert fist[1] - tall["head"][1] == pytest.approx(square_fist[1] - square["head"][1], abs=0.02), (tall, square)
        assert 0.15 < fist[2] - tall["head"][2] < 0.30 and abs(fist[0]) < 0.12, tall
    # A block faces its target (the opponent): with it 35° to the right, the trunk turns that way and the gloves with it.
    # The opponent then goes round to 35° to the left: the trunk follows it while the block holds.
    for label, degrees in (("facing_blocking", -35.0), ("facing_followed", 35.0)):
        facing = samples[label]
        middle = [(a + b) / 2 for a, b in zip(*facing["fists"], strict=True)]
        assert facing["blocking"] and math.degrees(math.atan2(middle[0], middle[2])) == pytest.approx(degrees, abs=8.0), (label, facing)
    for label in ("after", "stopped"):  # 0.5 s up, then back in the guard it came from
        assert not samples[label]["blocking"], samples[label]
        for fist, guard in zip(samples[label]["fists"], samples["guard"]["fists"], strict=True):
            assert fist == pytest.approx(guard, abs=0.01), (label, samples)
    # The block braces its guard: the motors hold with twice their torque (the elbow's 60 N m) while it holds only.
    assert samples["blocking"]["elbow_torque_nm"] == samples["held"]["elbow_torque_nm"] == 120.0, samples
    for label in ("guard", "after", "stopped"):
        assert samples[label]["elbow_torque_nm"] == 60.0, (label, samples)
    assert report["punched"] and not report["blocking_after_punch"], report
    assert not report["refused"] and report["knocked_down"] and not report["refused_when_down"], report
    # The blocks said nothing: the only signals are the punch's and its own way back to guard (`auto_recover`).
    assert [name for name, _ in report["signals"]] == ["punch_started", "punch_finished", "recovered"], report["signals"]
    assert min(frame for _, frame in report["signals"]) >= 530, report["signals"]


def test_a_block_stops_jabs_and_crosses_at_the_head_and_the_body(tmp_path):
    from punch_trainer.pipelines.evaluation import EvalArgs, run_eval

    args = EvalArgs(policy=PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx",
                    scenario="blocks", placements=16, sigmas=[0.0], out=tmp_path)
    _, report = run_eval(args, progress=False)
    rows = {row["condition"]: row for row in report["evaluations"][0]["rows"]}
    for move in ("jab", "cross"):
        open_guard = rows[f"{move}, in guard"]["defended"]
        assert open_guard["landed"] >= 8, open_guard  # most land on the head of a character in guard
        for warning in ("0.15 s before", "at the command"):
            row = rows[f"{move}, blocking {warning}"]
            # The bar: at least 90% blocked (its fist's first contact an arm).
            assert row["successes"] >= 0.9 * row["punches"], row
            # The braced guard takes most of the impulse: what reaches the head is less than half the open guard's.
            assert row["defended"]["head_impulse_ns_mean"] < 0.5 * open_guard["head_impulse_ns_mean"], (row, open_guard)
    # A cross at the body meets the high guard's elbows and forearms too.
    body = rows["cross at the body, blocking 0.15 s before"]
    assert body["successes"] >= 0.9 * body["punches"], body
    # A defender stepping sideways while it blocks: it moved, its shell kept facing the puncher, nothing landed.
    for name in ("cross at a defender stepping to its right 0.7 m/s, blocking 0.15 s before",
                 "jab at a defender stepping to its left 0.7 m/s, blocking 0.15 s before"):
        row = rows[name]
        assert row["moved_m"] > 0.2 and row["defended"]["landed"] == 0, row
