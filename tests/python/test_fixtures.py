"""The shared fixture (also checked by the Rust core's tests) still matches onnxruntime in Python."""

import json

import numpy as np
import onnxruntime

from conftest import FIXTURES


def test_fixture_outputs_match_onnxruntime() -> None:
    expected = json.loads((FIXTURES / "tiny_actor_expected.json").read_text())
    session = onnxruntime.InferenceSession(str(FIXTURES / "tiny_actor.onnx"), providers=["CPUExecutionProvider"])
    inputs = np.asarray(expected["input"], dtype=np.float32).reshape(expected["batch"], expected["input_width"])
    for output, values in zip(session.get_outputs(), session.run(None, {"obs": inputs}), strict=True):
        np.testing.assert_allclose(values.ravel(), expected["outputs"][output.name], atol=1e-6)
