"""ONNX export verifies itself against onnxruntime, and refuses a file that disagrees with torch."""

import onnx
import pytest
import torch

from punch_trainer.errors import ExportError
from punch_trainer.learn.export import export_onnx, verify_export
from punch_trainer.pipelines.selfcheck import TinyActor


def test_export_has_dynamic_batch_names_and_metadata(tmp_path) -> None:
    torch.manual_seed(0)
    path = export_onnx(TinyActor(6, 3), 6, tmp_path / "actor.onnx", metadata={"reward": "straight", "frames": "50"})
    model = onnx.load(str(path))
    assert [i.name for i in model.graph.input] == ["obs"]
    assert [o.name for o in model.graph.output] == ["mean", "sigma"]
    batch_dim = model.graph.input[0].type.tensor_type.shape.dim[0]
    assert batch_dim.dim_param, "batch axis must be dynamic"
    assert {p.key: p.value for p in model.metadata_props} == {"reward": "straight", "frames": "50"}


def test_verification_catches_a_model_that_differs(tmp_path) -> None:
    torch.manual_seed(0)
    actor = TinyActor(6, 3)
    path = export_onnx(actor, 6, tmp_path / "actor.onnx")
    with torch.no_grad():
        actor.mean.bias += 0.01  # torch now differs from the exported file
    with pytest.raises(ExportError, match="differs from torch"):
        verify_export(actor, path, 6)
