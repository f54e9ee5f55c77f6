"""The smoke test of the real stack: headless Godot runs Jolt, loads the extension, and runs an ONNX model
made here with torch through ort, matching onnxruntime in Python within 1e-5."""

import onnxruntime
import pytest

from punch_trainer.pipelines.selfcheck import TOLERANCE, SelfCheckArgs, run_selfcheck


@pytest.mark.godot
def test_selfcheck_on_the_real_stack() -> None:
    report = run_selfcheck(SelfCheckArgs(batch=16, seed=3))
    assert report.physics_engine == "Jolt Physics"
    assert report.godot_version.startswith("4.")
    assert int(report.godot_version.split(".")[1].split("-")[0]) >= 6
    assert report.onnxruntime_version == onnxruntime.__version__
    assert report.onnxruntime_library.endswith(f"libonnxruntime.so.{onnxruntime.__version__}")
    assert "addons/punch_controller/bin" in report.onnxruntime_library
    assert report.max_abs_difference <= TOLERANCE
