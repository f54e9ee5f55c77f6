"""The Godot runner fails a run on fatal log lines even when Godot exits 0, and explains an unusable $GODOT."""

import os
import stat

import pytest

from punch_trainer.errors import GodotNotFoundError, GodotRunError
from punch_trainer.sim.godot import GODOT_PROJECT, GODOT_WRAPPER, GodotRun, run_godot


@pytest.mark.parametrize(
    "line",
    [
        "SCRIPT ERROR: Parse Error: Identifier \"nope\" not declared in the current scope.",
        "ERROR: Can't open dynamic library: bin/libpunch_controller.so.",
        "WARNING: ObjectDB instances leaked at exit (run with --verbose for details).",
    ],
)
def test_fatal_lines_are_found(line: str) -> None:
    assert GodotRun(0, f"Godot Engine v4.6\n{line}\n").fatal_lines() == [line]


def test_ordinary_errors_are_not_fatal() -> None:
    # Errors that a test provokes on purpose (a bad model) are logged, not fatal.
    assert GodotRun(0, "ERROR: PunchPolicy: invalid ONNX model: bad bytes\n").fatal_lines() == []


@pytest.mark.godot
def test_script_error_fails_a_run_that_exits_zero(tmp_path) -> None:
    script = tmp_path / "broken.gd"
    script.write_text("extends SceneTree\nfunc _initialize() -> void:\n\tvar x = undefined_name\n\tquit(0)\n")
    with pytest.raises(GodotRunError, match="SCRIPT ERROR|Parse Error|exit code"):
        run_godot(["--headless", "--path", str(GODOT_PROJECT), "--script", str(script)], timeout_s=60)


@pytest.mark.godot
def test_leaked_objects_fail_a_run(tmp_path) -> None:
    script = tmp_path / "leak.gd"
    script.write_text("extends SceneTree\nfunc _initialize() -> void:\n\tNode.new()\n\tquit(0)\n")
    with pytest.raises(GodotRunError, match="leaked"):
        run_godot(["--headless", "--path", str(GODOT_PROJECT), "--script", str(script)], timeout_s=60)


@pytest.mark.parametrize("kind", ["not_executable", "not_godot", "too_old"])
def test_unusable_godot_variable_is_explained(tmp_path, monkeypatch, kind: str) -> None:
    fake = tmp_path / "godot"
    fake.write_text({
        "not_executable": "just text",
        "not_godot": "#!/bin/sh\necho hello\n",
        "too_old": "#!/bin/sh\necho 4.3.stable.official.77dcf97d8\n",
    }[kind])
    if kind != "not_executable":
        fake.chmod(fake.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("GODOT", str(fake))
    with pytest.raises(GodotNotFoundError, match="GODOT=") as error:
        run_godot(["--headless", "--version"])
    assert {"not_executable": "not an executable", "not_godot": "not a Godot executable",
            "too_old": "needs Godot >= 4.6"}[kind] in str(error.value)


def test_wrapper_is_executable() -> None:
    assert os.access(GODOT_WRAPPER, os.X_OK)
