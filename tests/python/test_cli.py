"""The `punch` console command is installed and answers."""

import subprocess
import sys
from pathlib import Path

import pytest

from punch_trainer import __version__
from punch_trainer.sim.godot import ADDON_POLICIES

PUNCH = Path(sys.executable).with_name("punch")


def test_version() -> None:
    result = subprocess.run([PUNCH, "--version"], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == f"punch {__version__}"


def test_selfcheck_bench_and_experiment_options_are_their_args_dataclasses() -> None:
    """Each option's default is its dataclass field's, and the commands the docs show parse to the same values."""
    from punch_trainer.cli.arguments import dataclass_from_arguments
    from punch_trainer.cli.main import build_parser
    from punch_trainer.pipelines.bench import DEMO_POLICY, BenchEnvArgs, BenchInferenceArgs, BenchSearchArgs
    from punch_trainer.pipelines.experiments import AfterPunchArgs, Fig6Args
    from punch_trainer.pipelines.selfcheck import SelfCheckArgs

    dataset = Path("runs/NAME/search/dataset.npz")
    cases = [
        ("selfcheck", SelfCheckArgs()),
        ("selfcheck --batch 16 --seed 3", SelfCheckArgs(batch=16, seed=3)),
        ("bench env", BenchEnvArgs()),
        ("bench env --ray simulated --no-write", BenchEnvArgs()),
        ("bench env --characters 1 64 --processes 2 --frames 25 --episodes 2", BenchEnvArgs([1, 64], [2], 25, 2)),
        ("bench inference", BenchInferenceArgs(policy=DEMO_POLICY)),
        ("bench inference --characters 64 100", BenchInferenceArgs(characters=[64, 100])),
        ("bench inference --policy p.onnx --batches 1", BenchInferenceArgs(policy=Path("p.onnx"), batches=1)),
        ("bench search", BenchSearchArgs()),
        ("bench search --presets hook --seeds 4 5 --iterations 7 --rollouts 8", BenchSearchArgs(["hook"], [4, 5], 7, 8)),
        ("experiment fig6 --reward straight --seeds 0 1 2", Fig6Args()),
        ("experiment fig6 --reward hook --seeds 1 --search-iterations 2 --a2c-updates 3 --characters 4 --no-write",
         Fig6Args("hook", [1], 2, 3, 4)),
        (f"experiment after-punch {dataset}", AfterPunchArgs(dataset)),
        (f"experiment after-punch {dataset} --iterations 3 --rollouts 8 --seed 1", AfterPunchArgs(dataset, 3, 8, 1)),
    ]
    parser = build_parser()
    for command, expected in cases:
        parsed = parser.parse_args(command.split())
        assert dataclass_from_arguments(type(expected), parsed) == expected, command
        if "no_write" in parsed:
            assert parsed.no_write == ("--no-write" in command), command


def test_unknown_command_is_a_usage_error() -> None:
    result = subprocess.run([PUNCH, "no-such-command"], capture_output=True, text=True)
    assert result.returncode == 2
    assert "invalid choice" in result.stderr


@pytest.mark.godot  # `punch eval` starts its training server before it reads the policy's reward
def test_a_policy_whose_metadata_names_code_never_runs_it(tmp_path) -> None:
    """A model file is data: `punch_reward` naming a .py file or a module is refused, and the code is not run; `punch eval
    --reward` names the reward to score with instead."""
    import onnx

    marker = tmp_path / "ran"
    (tmp_path / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('x')\ndef reward(*a): return 0\n")
    demo = ADDON_POLICIES / "straight.onnx"
    for named in [f"{tmp_path / 'evil.py'}:reward", "evil:reward"]:
        model = onnx.load(str(demo))
        for prop in model.metadata_props:
            if prop.key == "punch_reward":
                prop.value = named
        policy = tmp_path / "lying.onnx"
        onnx.save(model, str(policy))
        for command in (["replay", "--policy", str(policy), "--episodes", "1"], ["eval", "--policy", str(policy)]):
            result = subprocess.run([PUNCH, *command], capture_output=True, text=True, cwd=tmp_path, timeout=120)
            assert result.returncode != 0 and "not a built-in preset" in result.stderr, result.stderr[-2000:]
            assert "Traceback" not in result.stderr and not marker.exists()
    # Told which reward to score with (`--reward`, as the refusal says), it measures the policy; the code never runs.
    result = subprocess.run([PUNCH, "eval", "--policy", str(policy), "--reward", "straight", "--placements", "4", "--sigmas", "0",
                             "--search-iterations", "0", "--out", str(tmp_path / "told")], capture_output=True, text=True, cwd=tmp_path,
                            timeout=300)
    assert result.returncode == 0 and (tmp_path / "told" / "report.md").exists(), result.stderr[-2000:]
    assert "reward `straight`" in (tmp_path / "told" / "report.md").read_text() and not marker.exists()


@pytest.mark.godot
def test_user_errors_are_punch_messages_not_tracebacks(tmp_path) -> None:
    """A reward that exits the process, an --out that cannot be a directory, and a model whose metadata is
    garbage each end with one `punch:` line and a non-zero exit; --debug shows the traceback."""
    import onnx

    (tmp_path / "quits.py").write_text("import sys\ndef reward(f):\n    sys.exit(0)\n")
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    demo = ADDON_POLICIES / "straight.onnx"
    model = onnx.load(str(demo))
    for prop in model.metadata_props:
        if prop.key == "punch_training_summary":
            prop.value = "{not json"
    garbage = tmp_path / "garbage.onnx"
    onnx.save(model, str(garbage))
    cases = [
        (["search", "--reward", f"{tmp_path / 'quits.py'}:reward", "--iterations", "1", "--rollouts", "8",
          "--out", str(tmp_path / "run")], "tried to exit the process"),
        (["search", "--reward", "straight", "--iterations", "1", "--rollouts", "8", "--out", str(blocker / "run")],
         "Not a directory"),
        (["replay", "--policy", str(garbage), "--episodes", "1", "--out", str(tmp_path / "replay")], "punch_training_summary is not JSON"),
    ]
    for command, message in cases:
        result = subprocess.run([PUNCH, *command], capture_output=True, text=True, timeout=300)
        assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
        assert result.stderr.strip().splitlines()[-1].startswith("punch: ") and message in result.stderr, result.stderr
    result = subprocess.run([PUNCH, "--debug", *cases[1][0]], capture_output=True, text=True, timeout=300)
    assert result.returncode != 0 and "Traceback" in result.stderr
