"""`punch eval-sizes` on a tiny set: 4 held-out placements at three arm scales and two sigmas, through
PunchController in headless Godot (`PunchCharacter.size_arms`); the table's structure, the lengths Godot reports,
hits counted; and an arm scale `size_arms` refuses, refused with its range before Godot and by Godot itself."""

import json
import subprocess
import sys

import pytest

from punch_trainer.cli import main as cli_main
from punch_trainer.errors import GodotRunError
from punch_trainer.pipelines.replay import policy_placements
from punch_trainer.pipelines.sizes_eval import (
    ARM_SCALE_RANGE,
    SCENE_ARM_LENGTHS_M,
    SizesEvalArgs,
    SizesEvalError,
    hits_cell,
    parse_proportions,
    run_sized_hits,
    run_sizes_eval,
)
from punch_trainer.sim.godot import ADDON_POLICIES

POLICY = ADDON_POLICIES / "straight.onnx"
SCALES = [0.75, 1.0, 1.25]


@pytest.mark.godot
def test_eval_sizes_reports_every_scale_and_sigma_and_counts_hits(tmp_path):
    run = subprocess.run([sys.executable, "-m", "punch_trainer.cli.main", "eval-sizes", "--policy", str(POLICY),
                          "--scales", ",".join(map(str, SCALES)), "--proportions", "0.7x0.85", "--sigmas", "0,0.3",
                          "--placements", "4",
                          "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads((tmp_path / "sizes.json").read_text())
    assert report["scales"] == SCALES and report["sigmas"] == [0.0, 0.3] and len(report["placements"]) == 4
    assert report["arm_scale_range"] == list(ARM_SCALE_RANGE)  # Godot's own, as PunchCharacter reports it
    assert [size["scale"] for size in report["sizes"]] == ["0.75", "1", "1.25", "0.7x0.85"]
    for size in report["sizes"]:
        # Upper arm and forearm times their scales, the shoulders as they are, as Godot measures them sized.
        assert size["upper_arm_m"] == pytest.approx(size["upper_arm_scale"] * SCENE_ARM_LENGTHS_M[0], abs=0.002), size
        assert size["forearm_m"] == pytest.approx(size["forearm_scale"] * SCENE_ARM_LENGTHS_M[1], abs=0.002), size
        assert size["shoulder_width_m"] == pytest.approx(SCENE_ARM_LENGTHS_M[2], abs=0.002), size
        assert [s["sigma"] for s in size["per_sigma"]] == [0.0, 0.3]
        for per_sigma in size["per_sigma"]:
            assert per_sigma["punches"] == 4 and 0 <= per_sigma["hits"] <= 4, size
            assert per_sigma["out_of_reach"] == 0, size  # the placements are inside the policy's reach volume
    own = report["sizes"][SCALES.index(1.0)]["per_sigma"][0]
    assert report["sizes"][-1]["upper_arm_m"] == pytest.approx(0.7 * SCENE_ARM_LENGTHS_M[0], abs=0.002)
    assert own["hits"] >= 3, own  # the shipped straight at its own arms hits most of them
    assert "| arm scale | upper arm (m) | forearm (m) | shoulders (m) | σ 0 | σ 0.3 |" in run.stdout
    for line in ("| 0.75 | 0.211 | 0.253 | 0.360 |", "| 1 | 0.282 | 0.337 | 0.360 |", "| 1.25 | 0.352 | 0.421 | 0.360 |",
                 "| 0.7x0.85 | 0.197 | 0.286 | 0.360 |"):
        assert line in run.stdout, run.stdout
    assert (tmp_path / "report.md").read_text().count("\n| ") == 2 + len(SCALES)  # header rule and one row a size


def test_each_count_carries_its_95_percent_interval():
    assert hits_cell(1931, 2048) == "1931/2048 (94%; 93-95%)"
    assert hits_cell(30, 32) == "30/32 (94%; 80-98%)"
    assert hits_cell(0, 0) == "0/0 (0%; 0-100%)"


@pytest.mark.parametrize("scales", ["0.5", "1,1.3", "nan"])
def test_an_arm_scale_outside_the_range_is_one_clear_error_before_godot(capsys, scales):
    assert cli_main.main(["eval-sizes", "--policy", str(POLICY), "--scales", scales]) == 1
    err = capsys.readouterr().err
    assert err.startswith("punch: arm scale ") and err.count("\n") == 1, err
    assert "outside the range PunchCharacter.size_arms accepts: 0.75 to 1.25 times" in err, err
    with pytest.raises(SizesEvalError, match=r"arm scale 0\.5 is outside the range .* 0\.75 to 1\.25"):
        run_sizes_eval(SizesEvalArgs(policy=POLICY, scales=[0.5]), progress=False)


def test_proportions_a_rig_may_not_have_are_one_clear_error_before_godot():
    with pytest.raises(SizesEvalError, match=r"proportions 0\.65x0\.7 are outside .* the arm 0\.75 to 1\.25 times"):
        run_sizes_eval(SizesEvalArgs(policy=POLICY, proportions=[(0.65, 0.7)]), progress=False)
    with pytest.raises(SizesEvalError, match=r"bad --proportions '0\.7-0\.8'"):
        parse_proportions("0.7-0.8")


def test_scales_that_are_no_numbers_are_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli_main.main(["eval-sizes", "--policy", str(POLICY), "--scales", "0.8,big"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "bad --scales '0.8,big'" in err.strip().splitlines()[-1], err


@pytest.mark.godot
def test_godot_refuses_a_scale_outside_the_range_with_its_reason_and_does_not_crash():
    """The check in Godot itself (a caller of `run_sized_hits` past the command's own check): size_arms's error
    names the range, the script stops with exit code 2, not a crash."""
    bags = policy_placements(POLICY, 1, 4242)
    with pytest.raises(GodotRunError, match="exit code 2") as error:
        run_sized_hits(POLICY, bags, [(0.5, 0.5)], [0.0], 4242, timeout_s=60)
    assert "outside 0.75..1.25" in error.value.log, error.value.log
    assert "error: sized_hits: PunchCharacter.size_arms refused the arm scale 0.5" in error.value.log, error.value.log


@pytest.mark.godot
def test_a_godot_past_its_deadline_is_stopped_with_the_commands_error():
    """The shared loop (`sim.godot.run_godot_tool`, eval-moving's too) keeps the deadline by the clock."""
    bags = policy_placements(POLICY, 1, 4242)
    with pytest.raises(SizesEvalError, match="the sized punches did not finish within 0 s"):
        run_sized_hits(POLICY, bags, [(1.0, 1.0)], [0.0], 4242, timeout_s=0.01)
