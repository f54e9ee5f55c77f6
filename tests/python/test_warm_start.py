"""`punch train --init-from`: A2C starts from an earlier run's best policy when the observation gained inputs;
the policy first acts exactly as the earlier one, whatever the new inputs say."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from punch_trainer.learn.checkpoint import save_checkpoint
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.warm_start import SNAPSHOT_KIND, WarmStartError, warm_start

EARLIER = ["fist_x", "bag_x", "root_spin", "episode_phase"]
NOW = ["fist_x", "bag_x", "root_spin", "arm_m", "forearm_m", "episode_phase"]


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
    assert warm_start(model, tmp_path, NOW, statistics) == ["arm_m", "forearm_m"]
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
        warm_start(ActorCritic(len(NOW), 10), tmp_path, NOW, np.zeros((4, len(NOW))))
    with pytest.raises(WarmStartError, match="cannot start from"):
        warm_start(ActorCritic(len(NOW), 10), tmp_path / "nowhere", NOW, np.zeros((4, len(NOW))))


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
        assert warm_start(model, source, NOW, np.zeros((4, len(NOW)))) == []
        with torch.no_grad():
            torch.testing.assert_close(model(observations)[0], expected(observations)[0])
