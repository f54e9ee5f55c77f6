"""`punch soup`: the mean of several policy files' weights, only among policies of one lineage."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import onnx
import onnxruntime
import pytest
import torch

from punch_trainer.cli.main import main
from punch_trainer.learn.export import export_policy
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.soup import SoupError, soup
from punch_trainer.learn.warm_start import actor_parameters
from punch_trainer.policy_file import read_entries

OBSERVATIONS, ACTIONS = 6, 10
REACH = '{"any_start_pose": false, "distance_m": [0.72, 0.72], "height_m": [1.35, 1.35], "side_m": [0, 0], "max_target_speed_mps": 0}'
CONTRACT = {"punch_spec_hash": "b3b18e1568362141", "punch_observation_size": str(OBSERVATIONS),
            "punch_action_size": str(ACTIONS), "punch_decision_period": "5", "punch_frames": "50", "punch_physics_hz": "120",
            "punch_smoothing_window": "3", "punch_reach_volume": REACH}
NORMALISATION = np.random.default_rng(0).normal(1.0, 2.0, size=(100, OBSERVATIONS))


def fine_tuned(folder: Path, name: str, seed: int, *, contract: dict[str, str] = CONTRACT,
               normalisation: np.ndarray = NORMALISATION) -> tuple[Path, ActorCritic]:
    """A policy file as a round of A2C from one parent writes it: the parent's normalisation, other weights."""
    model = ActorCritic(OBSERVATIONS, ACTIONS, seed=seed)
    model.set_normalization(normalisation)
    path = export_policy(model, folder / f"{name}.onnx", contract=contract, reward="straight",
                         summary={"search_best_return": 0.25, "a2c_snapshot_update": seed, "run": name})
    return path, model


def metadata_of(path: Path) -> dict[str, str]:
    return read_entries(path)


def test_a_soup_acts_with_the_mean_of_its_ingredients_weights_and_says_what_they_were(tmp_path: Path) -> None:
    (a, model_a), (b, model_b), (c, model_c) = (fine_tuned(tmp_path, name, seed) for name, seed in
                                                 (("a", 1), ("b", 2), ("c", 3)))
    out = soup([a, b, c], tmp_path / "soup.onnx")

    mean = ActorCritic(OBSERVATIONS, ACTIONS)
    mean.load_state_dict({key: (model_a.state_dict()[key] + model_b.state_dict()[key] + model_c.state_dict()[key]) / 3
                          for key in mean.state_dict()})
    observations = np.random.default_rng(1).normal(size=(32, OBSERVATIONS)).astype(np.float32)
    ours = onnxruntime.InferenceSession(str(out), providers=["CPUExecutionProvider"]).run(None, {"obs": observations})
    with torch.no_grad():
        theirs = mean(torch.from_numpy(observations))
    for got, expected in zip(ours, theirs, strict=True):
        np.testing.assert_allclose(got, expected.numpy(), atol=1e-5)
    # and it is no ingredient: the mean moved every weight
    assert not torch.allclose(actor_parameters(onnx.load(str(out)))["mean_head.weight"], model_a.mean_head.weight)

    metadata = metadata_of(out)
    assert {key: metadata[key] for key in CONTRACT} == CONTRACT
    assert metadata["punch_reward"] == "straight" and metadata["punch_style"] == "none"
    summary = json.loads(metadata["punch_training_summary"])
    assert summary["search_best_return"] == 0.25  # what `punch replay` reads from every policy file
    assert [entry["sha256"] for entry in summary["soup"]] == [hashlib.sha256(p.read_bytes()).hexdigest() for p in (a, b, c)]
    assert [entry["summary"]["run"] for entry in summary["soup"]] == ["a", "b", "c"]


def test_a_soup_of_one_policy_twice_acts_as_that_policy(tmp_path: Path) -> None:
    a, _ = fine_tuned(tmp_path, "a", 1)
    out = soup([a, a], tmp_path / "soup.onnx")
    observations = np.random.default_rng(2).normal(size=(16, OBSERVATIONS)).astype(np.float32)
    run = lambda path: onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"]).run(None, {"obs": observations})  # noqa: E731
    for got, expected in zip(run(out), run(a), strict=True):
        np.testing.assert_allclose(got, expected, atol=1e-6)


def test_policies_not_of_one_lineage_are_refused_and_nothing_is_written(tmp_path: Path) -> None:
    a, _ = fine_tuned(tmp_path, "a", 1)
    other_parent, _ = fine_tuned(tmp_path, "other_parent", 2, normalisation=NORMALISATION + 1.0)
    other_reward, _ = fine_tuned(tmp_path, "other_spec", 3, contract={**CONTRACT, "punch_decision_period": "4"})
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"not a policy")
    broken_model = ActorCritic(OBSERVATIONS, ACTIONS, seed=4)
    broken_model.set_normalization(NORMALISATION)
    with torch.no_grad():
        broken_model.mean_head.weight[0, 0] = float("nan")
    broken = export_policy(broken_model, tmp_path / "broken.onnx", contract=CONTRACT, reward="straight", summary={},
                           verify=False)
    out = tmp_path / "soup.onnx"
    for policies, message in (([a, other_parent], "normalises its observation otherwise"),
                              ([a, other_reward], "differs from .* in punch_decision_period"),
                              ([a, garbage], "not a readable policy file"),
                              ([a, broken], "mean_head.weight are not all finite"),
                              ([a], "at least two policies")):
        with pytest.raises(SoupError, match=message):
            soup(policies, out)
        assert not out.exists()


def test_punch_soup_writes_the_file_and_reports_a_refusal_as_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, _ = fine_tuned(tmp_path, "a", 1)
    b, _ = fine_tuned(tmp_path, "b", 2)
    assert main(["soup", str(a), str(b), "--out", str(tmp_path / "soup.onnx")]) == 0
    assert "averaged the weights of 2 policies" in capsys.readouterr().out
    assert (tmp_path / "soup.onnx").is_file()
    assert main(["soup", str(a), "--out", str(tmp_path / "lone.onnx")]) != 0
    assert "at least two policies" in capsys.readouterr().err
