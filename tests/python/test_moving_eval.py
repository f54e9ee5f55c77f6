"""`punch eval-moving` (issue 31) on a tiny set: 2 held-out placements, a standing and a walking case, sigma 0,
through PunchController in headless Godot; the report's structure, and the standing punches hit."""

import json
import subprocess
import sys

import pytest

from punch_trainer.pipelines.moving_eval import MOVING_CASES, MovingEvalError, select_cases
from punch_trainer.sim.godot import ADDON_POLICIES

pytestmark = pytest.mark.godot

CASES = ["standing", "forward 0.7 m/s"]


def test_the_cases_are_named_once_and_an_unknown_one_is_refused():
    names = [case.name for case in MOVING_CASES]
    assert len(set(names)) == len(names)
    assert [case.name for case in select_cases(CASES)] == CASES
    with pytest.raises(MovingEvalError, match="unknown motion case"):
        select_cases(["moonwalk"])


def test_eval_moving_reports_every_case_and_the_standing_punches_hit(tmp_path):
    policy = ADDON_POLICIES / "straight.onnx"
    run = subprocess.run([sys.executable, "-m", "punch_trainer.cli.main", "eval-moving", "--policy", str(policy),
                          "--placements", "2", "--sigmas", "0", "--cases", *CASES, "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads((tmp_path / "moving.json").read_text())
    assert len(report["placements"]) == 2 and report["sigmas"] == [0.0]
    (evaluation,) = report["evaluations"]
    assert [case["case"] for case in evaluation["cases"]] == CASES
    for case in evaluation["cases"]:
        (sigma0,) = case["per_sigma"]
        assert sigma0["punches"] == 2 and 0 <= sigma0["hits"] <= 2, case
    standing, walking = evaluation["cases"]
    assert standing["per_sigma"][0]["hits"] == 2, standing
    assert standing["moved_m"] == 0.0
    # Walking for the 0.5 s lead (`--lead-s`), then the 50 frames of a punch at 120 Hz (and the few frames a
    # character walked out of its guard takes to return to it first: `guard_first`).
    assert 0.7 * (0.5 + 50 / 120) - 0.02 <= walking["moved_m"] <= 0.7 * (0.5 + 0.2 + 50 / 120)
    assert report["lead_s"] == 0.5
    table = (tmp_path / "report.md").read_text()
    assert "| standing | 2/2 |" in table
    assert "| case | straight σ 0 |" in run.stdout


def test_eval_moving_sizes_the_arms_it_is_given(tmp_path):
    """`--arms UxF`: every character's arms sized through size_arms (short ones here), as a rig would size them;
    the straight still lands from standing and reports the size it ran with. Of the two placements, the first
    (0.73 m ahead) is well within these arms' reach; the second (0.84 m ahead, 1.48 m up) is the reach volume's far
    corner, where the shipped straight with these arms lands some punches and not others (over 1,024 placements
    998, `punch eval-sizes --proportions 0.8x0.75 --seed 999`), so only the first must land."""
    policy = ADDON_POLICIES / "straight.onnx"
    run = subprocess.run([sys.executable, "-m", "punch_trainer.cli.main", "eval-moving", "--policy", str(policy),
                          "--placements", "2", "--sigmas", "0", "--cases", *CASES, "--arms", "0.8x0.75",
                          "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads((tmp_path / "moving.json").read_text())
    assert report["arms"] == [0.8, 0.75]
    standing = report["evaluations"][0]["cases"][0]
    assert 0 in standing["per_sigma"][0]["hit_placements"], standing
    assert "arms 0.8x0.75 times" in (tmp_path / "report.md").read_text()


def test_arms_a_rig_may_not_have_are_one_clear_error_before_godot(tmp_path):
    run = subprocess.run([sys.executable, "-m", "punch_trainer.cli.main", "eval-moving", "--policy",
                          str(ADDON_POLICIES / "straight.onnx"), "--arms", "0.6", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode != 0
    assert "outside what PunchCharacter.size_arms accepts" in run.stderr, run.stderr[-2000:]
    assert not (tmp_path / "moving.json").exists()
