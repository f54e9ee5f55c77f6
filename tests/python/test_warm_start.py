"""`punch train --init-from`: A2C starts from an earlier run's best policy when the observation gained inputs;
the policy first acts exactly as the earlier one, whatever the new inputs say."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from punch_trainer.learn.checkpoint import save_checkpoint
from punch_trainer.learn.export import export_policy
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.pretrain import fit_critic
from punch_trainer.learn.warm_start import SNAPSHOT_KIND, WarmStartError, check_source, warm_start

EARLIER = ["fist_x", "bag_x", "root_spin", "episode_phase"]
NOW = ["fist_x", "bag_x", "root_spin", "arm_m", "forearm_m", "episode_phase"]
SPEC = "b3b18e1568362141"
REACH = '{"any_start_pose": false, "distance_m": [0.72, 0.72], "height_m": [1.35, 1.35], "side_m": [0, 0], "max_target_speed_mps": 0}'


def contract(spec: str = SPEC) -> dict[str, str]:
    """A policy contract as `punch train` writes it, for an observation of NOW."""
    return {"punch_spec_hash": spec, "punch_observation_size": str(len(NOW)), "punch_action_size": "10",
            "punch_decision_period": "5", "punch_frames": "50", "punch_physics_hz": "120", "punch_smoothing_window": "3",
            "punch_reach_volume": REACH}


def earlier_run(folder: Path, names: list[str] = EARLIER) -> ActorCritic:
    """A finished run's folder: its search dataset's observation names and its A2C checkpoint's best model."""
    model = ActorCritic(len(names), 10, seed=3)
    model.set_normalization(np.random.default_rng(0).normal(1.0, 2.0, size=(100, len(names))))
    (folder / "search").mkdir(parents=True)
    np.savez(folder / "search" / "dataset.npz", observation_names=np.array(names))
    (folder / "a2c").mkdir()
    save_checkpoint(folder / "a2c", "a2c", {"best_model": model.state_dict()})
    return model


def test_a_warm_started_policy_acts_as_the_earlier_one_and_normalises_its_new_inputs(tmp_path: Path) -> None:
    earlier = earlier_run(tmp_path)
    model = ActorCritic(len(NOW), 10, seed=0)
    statistics = np.random.default_rng(1).normal(0.3, 0.05, size=(200, len(NOW)))
    assert warm_start(model, tmp_path, NOW, statistics, SPEC) == ["arm_m", "forearm_m"]
    observations = torch.as_tensor(np.random.default_rng(2).normal(size=(16, len(NOW))), dtype=torch.float32)
    kept = [NOW.index(name) for name in EARLIER]
    with torch.no_grad():
        for ours, theirs in zip(model(observations), earlier(observations[:, kept]), strict=True):
            torch.testing.assert_close(ours, theirs)
        torch.testing.assert_close(model.value(observations), earlier.value(observations[:, kept]))
    new = [NOW.index("arm_m"), NOW.index("forearm_m")]
    np.testing.assert_allclose(model.obs_mean[new].numpy(), statistics[:, new].mean(axis=0), rtol=1e-5)


def test_a_run_whose_policy_observes_what_this_one_does_not_is_refused(tmp_path: Path) -> None:
    earlier_run(tmp_path, ["fist_x", "gone", "episode_phase"])
    with pytest.raises(WarmStartError, match="observes gone"):
        warm_start(ActorCritic(len(NOW), 10), tmp_path, NOW, np.zeros((4, len(NOW))), SPEC)
    with pytest.raises(WarmStartError, match="cannot start from"):
        warm_start(ActorCritic(len(NOW), 10), tmp_path / "nowhere", NOW, np.zeros((4, len(NOW))), SPEC)


def test_a_snapshot_is_started_from_as_it_was_not_the_runs_best(tmp_path: Path) -> None:
    """`--init-from RUN/a2c/snapshots/update_<N>`: the model as A2C had it then (`--a2c-snapshot-every`)."""
    best = earlier_run(tmp_path, NOW)
    snapshot = ActorCritic(len(NOW), 10, seed=7)
    snapshot.set_normalization(np.random.default_rng(4).normal(size=(100, len(NOW))))
    folder = tmp_path / "a2c" / "snapshots" / "update_00200"
    folder.mkdir(parents=True)
    save_checkpoint(folder, SNAPSHOT_KIND, {"update": 200, "model": snapshot.state_dict()})
    observations = torch.as_tensor(np.random.default_rng(5).normal(size=(8, len(NOW))), dtype=torch.float32)
    for source, expected in ((folder, snapshot), (tmp_path, best)):
        model = ActorCritic(len(NOW), 10, seed=0)
        assert warm_start(model, source, NOW, np.zeros((4, len(NOW))), SPEC) == []
        with torch.no_grad():
            torch.testing.assert_close(model(observations)[0], expected(observations)[0])


def test_a_policy_file_is_started_from_with_its_actor_and_a_critic_fitted_here(tmp_path: Path) -> None:
    """`--init-from addons/punch_controller/policies/hook.onnx`: the file's actor acts as it did; the file holds
    no critic, so the run's fresh one is fitted to the search's returns-to-go, the actor untouched."""
    shipped = ActorCritic(len(NOW), 10, seed=3)
    shipped.set_normalization(np.random.default_rng(0).normal(1.0, 2.0, size=(100, len(NOW))))
    path = export_policy(shipped, tmp_path / "policy.onnx", contract=contract(), reward="hook", summary={})
    model = ActorCritic(len(NOW), 10, seed=0)
    fresh_critic = {key: value.clone() for key, value in model.state_dict().items() if key.startswith("critic.")}
    assert warm_start(model, path, NOW, np.zeros((4, len(NOW))), SPEC) == []
    observations = torch.as_tensor(np.random.default_rng(5).normal(size=(8, len(NOW))), dtype=torch.float32)
    with torch.no_grad():
        for ours, theirs in zip(model(observations), shipped(observations), strict=True):
            torch.testing.assert_close(ours, theirs)
    for key, value in fresh_critic.items():
        torch.testing.assert_close(model.state_dict()[key], value)

    rng = np.random.default_rng(6)
    data = {"observations": rng.normal(size=(256, len(NOW))).astype(np.float32)}
    data["returns_to_go"] = (2.0 + data["observations"][:, 0]).astype(np.float32)
    before = torch.mean((model.value(torch.as_tensor(data["observations"])) - torch.as_tensor(data["returns_to_go"])) ** 2)
    history = fit_critic(model, data, epochs=200, progress=False)
    assert history[-1]["critic_mse"] < 0.1 * before.item()
    with torch.no_grad():
        torch.testing.assert_close(model(observations)[0], shipped(observations)[0])


def test_a_policy_file_of_another_observation_spec_or_no_policy_at_all_is_refused(tmp_path: Path) -> None:
    other = export_policy(ActorCritic(len(NOW), 10), tmp_path / "other.onnx", reward="hook", summary={},
                          contract=contract("0000000000000000"))
    with pytest.raises(WarmStartError, match="observation spec"):
        warm_start(ActorCritic(len(NOW), 10), other, NOW, np.zeros((4, len(NOW))), SPEC)
    lying = tmp_path / "lying.onnx"
    lying.write_bytes(b"not a policy")
    with pytest.raises(WarmStartError, match="not a readable policy file"):
        warm_start(ActorCritic(len(NOW), 10), lying, NOW, np.zeros((4, len(NOW))), SPEC)


def test_a_source_with_nothing_to_start_from_is_refused_before_any_training(tmp_path: Path) -> None:
    with pytest.raises(WarmStartError, match="no such policy file"):
        check_source(tmp_path / "missing.onnx")
    (tmp_path / "recipe_run" / "stage").mkdir(parents=True)
    with pytest.raises(WarmStartError, match="neither a finished `punch train` run"):
        check_source(tmp_path / "recipe_run")
    earlier_run(tmp_path / "run")
    check_source(tmp_path / "run")
