"""Every option and metadata value is checked at the boundary, before any work starts, with one `punch:` line:
non-finite, negative, zero or absurd sizes are refused, each numeric option of every command has bounds
(stated in its --help), and a killed `punch eval` leaves no temporary files."""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
import typing

import onnx
import pytest

from conftest import PROJECT_ROOT
from punch_trainer.cli import main as cli_main
from punch_trainer.learn.reach import ReachError, ReachVolume
from punch_trainer.options import field_bounds

POLICY = str(PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx")


def all_args_types() -> list[type]:
    """Every *Args dataclass a command is built from."""
    import punch_trainer.learn.a2c as a2c
    import punch_trainer.learn.volume as volume

    seen = {a2c.A2CArgs, volume.VolumeArgs}
    for module in list(sys.modules.values()):
        if getattr(module, "__name__", "").startswith("punch_trainer."):
            seen |= {value for name, value in vars(module).items()
                     if name.endswith("Args") and dataclasses.is_dataclass(value) and isinstance(value, type)}
    return sorted(seen, key=lambda t: t.__name__)


def test_every_numeric_option_has_bounds():
    missing = []
    for args_type in all_args_types():
        hints = typing.get_type_hints(args_type)
        for field in dataclasses.fields(args_type):
            text = str(hints[field.name])
            if ("int" in text or "float" in text) and field_bounds(field) is None:
                missing.append(f"{args_type.__name__}.{field.name}")
    assert len(all_args_types()) >= 12
    assert not missing, f"numeric options without bounds (punch_trainer/options.py): {missing}"



def test_an_option_whose_help_gives_0_a_meaning_accepts_0():
    """`--search-iterations 0` of punch eval means no search (its help says so): its bounds may not refuse it."""
    from punch_trainer.cli.arguments import field_docs

    refused = [f"{args_type.__name__}.{field.name}" for args_type in all_args_types() for field in dataclasses.fields(args_type)
               if "(0: " in field_docs(args_type).get(field.name, "") and (bounds := field_bounds(field)) is not None
               and bounds.refuses(0)]
    assert not refused, f"options whose help gives 0 a meaning, and whose bounds refuse it: {refused}"


@pytest.mark.parametrize("arguments, message", [
    (["eval", "--policy", POLICY, "--sigmas", "inf"], "--sigmas inf: must be a finite number"),
    (["eval", "--policy", POLICY, "--sigmas", "5"], "--sigmas 5.0: must be at least 0, at most 1"),
    (["eval", "--policy", POLICY, "--sigmas", "0,-1"], "--sigmas -1.0: must be at least 0"),
    (["eval", "--policy", POLICY, "--sigmas", "nan"], "--sigmas nan: must be a finite number"),
    (["eval", "--policy", POLICY, "--placements", "0"], "--placements 0: must be at least 1"),
    (["replay", "--policy", POLICY, "--characters", "0"], "--characters 0: must be at least 1"),
    (["replay", "--policy", POLICY, "--episodes", "1000000000"], "--episodes 1000000000: must be at least 1, at most 100000"),
    (["replay", "--policy", POLICY, "--seed", "-2"], "--seed -2: must be at least 0"),
    (["render", "--sigmas", "1.5"], "--sigmas 1.5"),
    (["render", "--seconds", "inf"], "--seconds inf: must be a finite number"),
    (["search", "--iterations", "-3"], "--iterations -3: must be at least 1"),
    (["search", "--frames", "0"], "--frames 0: must be at least 1"),
    (["search", "--sigma-init", "0"], "--sigma-init 0.0: must be more than 0"),
    (["search", "--time-budget-s", "nan"], "--time-budget-s nan: must be a finite number"),
    (["train", "--default-share", "2"], "--default-share 2.0: must be at least 0, at most 1"),
    (["train", "--a2c-characters", "100000"], "--a2c-characters 100000: must be at least 1, at most 4096"),
    (["train", "--grid", "1000000,1000,1000"], "--grid 1000000: must be at least 1, at most 50"),
    (["train", "--grid", "0,3,3"], "--grid 0: must be at least 1"),
    (["train", "--grid", "3,3"], "--grid '3,3': must be three whole numbers"),
    (["selfcheck", "--batch", "0"], "--batch 0: must be at least 1"),
    (["bench", "env", "--characters", "1", "0"], "--characters 0: must be at least 1"),
])
def test_bad_options_are_one_punch_line_before_any_work(capsys, arguments, message):
    started = time.monotonic()
    assert cli_main.main(arguments) == 1
    err = capsys.readouterr().err
    assert err.startswith("punch: ") and err.count("\n") == 1 and message in err, err
    assert time.monotonic() - started < 10  # refused at once: no Godot was started


def test_a_grid_of_no_sense_in_a_runs_config_is_refused_before_any_work(tmp_path, capsys):
    """`punch train --resume` reads --grid back from config.json: checked as on the command line (a tampered
    10^12-placement grid was found out only after the first search, as a MemoryError traceback)."""
    from punch_trainer.learn.checkpoint import write_config
    from punch_trainer.pipelines.train import TrainArgs

    write_config(tmp_path, TrainArgs(out=tmp_path, grid="1000000,1000,1000"))
    started = time.monotonic()
    assert cli_main.main(["train", "--resume", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("punch: ") and err.count("\n") == 1 and "grid 1000000: must be at least 1, at most 50" in err, err
    assert time.monotonic() - started < 10


@pytest.mark.parametrize("sigmas, message", [
    ("0:1:1e-12", "at most 100"),
    ("0:inf:0.1", "must be finite"),
    ("1:0:0.1", "at least 1"),
    ("0:1:0", "step > 0"),
    ("a,b", "could not convert"),
    ("bags:1e30,1.3,0", "is not distance,height,side"),
    ("bags:0.7,1.3,0;0.7,nan,0", "'0.7,nan,0' is not distance,height,side"),
    ("bags:0.7,1.3", "is not distance,height,side"),
])
def test_bad_sigma_ranges_and_bags_are_usage_errors(capsys, sigmas, message):
    command = (["render", "--bags", sigmas.removeprefix("bags:")] if sigmas.startswith("bags:")
               else ["eval", "--policy", POLICY, "--sigmas", sigmas])
    with pytest.raises(SystemExit) as exit_:
        cli_main.main(command)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and message in err.strip().splitlines()[-1], err


def test_help_states_the_bounds(capsys):
    with pytest.raises(SystemExit):
        cli_main.main(["replay", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "punches per sigma (at least 1, at most 100000)" in text
    assert "(at least 0, at most 1, at most 100 values)" in text


@pytest.mark.parametrize("reach, message", [
    ({"distance_m": [0.6, 1e30]}, "distance_m"),
    ({"height_m": [1.5, 1.2]}, "height_m"),
    ({"side_m": [float("nan"), 0.2]}, "side_m"),
    ({"max_target_speed_mps": -1}, "max_target_speed_mps"),
    ({"any_start_pose": "yes"}, "any_start_pose"),
    ({"distance_m": [0.6]}, "malformed"),
    ({"distance_m": "far"}, "malformed"),
])
def test_a_reach_volume_of_no_sense_is_refused(reach, message):
    good = {"distance_m": [0.6, 0.85], "height_m": [1.15, 1.55], "side_m": [-0.25, 0.25], "max_target_speed_mps": 1.0,
            "any_start_pose": True}
    assert ReachVolume.from_json(json.dumps(good)).distance_m == (0.6, 0.85)
    with pytest.raises(ReachError, match=message):
        ReachVolume.from_json({**good, **reach})


@pytest.mark.parametrize("summary, message", [
    ("[1, 2]", "is a list, not an object"),
    ('{"search_best_return": NaN}', "is not JSON"),
    ('{"search_best_return": "12"}', "'12' is not a finite number"),
    ("{not json", "is not JSON"),
])
def test_a_policy_summary_of_no_sense_is_refused_before_godot(tmp_path, capsys, summary, message):
    model = onnx.load(POLICY)
    for prop in model.metadata_props:
        if prop.key == "punch_training_summary":
            prop.value = summary
    policy = tmp_path / "odd.onnx"
    onnx.save(model, str(policy))
    started = time.monotonic()
    assert cli_main.main(["replay", "--policy", str(policy), "--episodes", "1", "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("punch: ") and message in err, err
    assert not (tmp_path / "out").exists() and time.monotonic() - started < 10


@pytest.mark.godot
def test_a_terminated_eval_leaves_no_temporary_files(tmp_path):
    """SIGTERM mid-evaluation unwinds like Ctrl-C: the scratch folder Godot wrote into is removed."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    process = subprocess.Popen([sys.executable, "-m", "punch_trainer.cli.main", "eval", "--policy", POLICY, "--placements", "64",
                                "--sigmas", "0", "--noisy-episodes", "1", "--search-iterations", "1", "--out", str(tmp_path / "eval")],
                               cwd=PROJECT_ROOT, env={**os.environ, "TMPDIR": str(scratch)}, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not any(scratch.glob("punch_eval_*/features*")) and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
    assert process.poll() is None, process.communicate()
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130 and "punch: interrupted (SIGTERM)" in err, err
    assert not list(scratch.glob("punch_*")), list(scratch.rglob("*"))  # (.ses: a library's 51-byte session file)
