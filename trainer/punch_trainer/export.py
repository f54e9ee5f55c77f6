"""ONNX export of policies, verified against onnxruntime on sampled inputs before it is trusted."""

from __future__ import annotations

import contextlib
import io
import logging
from pathlib import Path

import numpy as np
import onnx
import onnxruntime
import torch

from punch_trainer.errors import ExportError

EXPORT_TOLERANCE = 1e-5

# The exporter logs a warning for each torchvision operator it cannot register; we export no such operator.
logging.getLogger("torch.onnx._internal.exporter._registration").setLevel(logging.ERROR)


def export_policy(
    module: torch.nn.Module,
    input_width: int,
    path: Path,
    *,
    input_name: str = "obs",
    output_names: tuple[str, ...] = ("mean", "sigma"),
    metadata: dict[str, str] | None = None,
    seed: int = 0,
    verify: bool = True,
) -> Path:
    """Exports `module` (input [batch, input_width] -> outputs [batch, k]) to `path` with a dynamic batch
    axis and string metadata, then checks that onnxruntime reproduces torch within EXPORT_TOLERANCE on
    random inputs (unless `verify` is off: for test models that output NaN on purpose). Raises ExportError
    otherwise."""
    module = module.eval()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    example = torch.zeros(2, input_width)
    batch = torch.export.Dim("batch")
    with contextlib.redirect_stdout(io.StringIO()):  # the exporter narrates each stage
        torch.onnx.export(
            module,
            (example,),
            str(path),
            input_names=[input_name],
            output_names=list(output_names),
            dynamic_shapes=({0: batch},),
            dynamo=True,
            external_data=False,
        )
    model = onnx.load(str(path))
    for key, value in (metadata or {}).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, str(value)
    onnx.save(model, str(path))
    if verify:
        verify_export(module, path, input_width, input_name=input_name, seed=seed)
    return path


def verify_export(module: torch.nn.Module, path: Path, input_width: int, *, input_name: str = "obs", seed: int = 0) -> float:
    """Largest |torch - onnxruntime| over sampled inputs; raises ExportError above EXPORT_TOLERANCE."""
    inputs = np.random.default_rng(seed).normal(size=(64, input_width)).astype(np.float32)
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    onnx_outputs = session.run(None, {input_name: inputs})
    with torch.no_grad():
        torch_outputs = module(torch.from_numpy(inputs))
    if isinstance(torch_outputs, torch.Tensor):
        torch_outputs = (torch_outputs,)
    worst = max(float(np.max(np.abs(o - t.numpy()))) for o, t in zip(onnx_outputs, torch_outputs, strict=True))
    if not worst <= EXPORT_TOLERANCE:
        raise ExportError(f"{path}: onnxruntime differs from torch by {worst:.3g} (> {EXPORT_TOLERANCE})")
    return worst
