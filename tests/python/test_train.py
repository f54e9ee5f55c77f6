"""The whole pipeline on a small budget: search, pretraining, A2C, export with metadata, replay."""

import csv
import json
import math

import onnx
import pytest

from punch_trainer.pipelines.train import TrainArgs, run_exported_policy, run_train
from punch_trainer.policy_file import read_entries
from punch_trainer.reward.rewards import load_reward, score
from punch_trainer.reward.style import style_named
from punch_trainer.sim.env import PunchVectorEnv

pytestmark = [pytest.mark.godot, pytest.mark.expensive]


@pytest.mark.parametrize("style", ["none", "boxing"])
def test_small_training_run_exports_a_policy_that_repeats_its_punch(tmp_path, style):
    """With a style too: A2C's decision-by-decision rewards add up to the episode's styled return, and the
    policy records its style."""
    args = TrainArgs(reward="straight", style=style, out=tmp_path / "run", search_iterations=4, search_rollouts=16,
                     pretrain_epochs=300, a2c_updates=2, a2c_characters=4, a2c_time_budget_s=0, reach="spot",
                     a2c_snapshot_every=1)
    out = run_train(args, progress=False)
    for name in ["policy.onnx", "report.md", "summary.json", "a2c_metrics.csv", "a2c_diagnostics.png", "search/dataset.npz"]:
        assert (out / name).is_file(), name
    # A2C's diagnostics, per update: losses, entropy, sigma and the reward's term (the straight preset has one).
    with open(out / "a2c_metrics.csv") as handle:
        updates = list(csv.DictReader(handle))[1:]
    assert len(updates) == 2
    for update in updates:
        for column in ["policy_loss", "value_loss", "entropy", "sigma_mean", "reward/forward"]:
            assert math.isfinite(float(update[column])), (column, update)
        assert float(update["reward/forward"]) == pytest.approx(float(update["mean_return"]), rel=1e-5)
    assert "a2c_diagnostics.png" in (out / "report.md").read_text()
    # The policy along the way, exported with the same contract, to be measured beside the one A2C kept.
    snapshots = sorted(p.name for p in (out / "a2c" / "snapshots").iterdir())
    assert snapshots == ["update_00001", "update_00002"]
    last = out / "a2c" / "snapshots" / snapshots[-1]
    assert (last / "checkpoint.pt").is_file()  # for `--init-from`
    snapshot = read_entries(last / "policy.onnx")
    model = onnx.load(str(out / "policy.onnx"))
    metadata = read_entries(out / "policy.onnx")
    assert {key: value for key, value in snapshot.items() if key != "punch_training_summary"} == \
        {key: value for key, value in metadata.items() if key != "punch_training_summary"}
    snapshot_summary = json.loads(snapshot["punch_training_summary"])
    assert snapshot_summary["a2c_snapshot_update"] == 2 and snapshot_summary["reach"] == "spot"
    assert snapshot_summary["search_best_return"] == json.loads(metadata["punch_training_summary"])["search_best_return"]
    for key in ["punch_spec_hash", "punch_action_spec", "punch_decision_period", "punch_smoothing_window",
                "punch_physics_hz", "punch_reward", "punch_training_summary"]:
        assert metadata.get(key), key
    assert metadata["punch_style"] == ("none" if style == "none" else "boxing@1")
    # A styled policy spreads a game's runtime noise as its style searched: the guard arm nearly still.
    assert ("punch_noise_scale" in metadata) == (style != "none")
    if style != "none":
        assert json.loads(metadata["punch_noise_scale"]) == [0.1, 1, 1, 1, 1, 1, 0.05, 0.05, 0.05, 0.05]
    assert json.loads((out / "config.json").read_text())["style"] == style
    assert [i.name for i in model.graph.input] == ["obs"] and [o.name for o in model.graph.output] == ["mean", "sigma"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["exported_return"] == pytest.approx(summary["exported_return"])  # a number, not NaN
    # With sigma = 0 the exported policy repeats the same punch exactly.
    reward = load_reward("straight", style=style_named(style))
    with PunchVectorEnv(1, 2, frames=50, smoothing_window=3) as env:
        first, features_a = run_exported_policy(out / "policy.onnx", env, reward)
        second, features_b = run_exported_policy(out / "policy.onnx", env, reward)
    assert first == second and (features_a == features_b).all()
    assert first == pytest.approx(summary["exported_return"])
    assert first == pytest.approx(float(score(reward, features_a, env.feature_names)), rel=1e-9, abs=1e-9)


def test_a_run_warm_started_from_the_addons_policy_file_punches_as_it_did(tmp_path):
    """`--init-from addons/punch_controller/policies/hook.onnx`: the file's actor, a critic fitted here, then A2C."""
    from pathlib import Path

    import numpy as np
    import onnxruntime

    shipped = Path(__file__).resolve().parents[2] / "addons" / "punch_controller" / "policies" / "hook.onnx"
    args = TrainArgs(reward="hook", style="none", out=tmp_path / "run", search_iterations=2, search_rollouts=16, a2c_updates=1,
                     a2c_characters=4, a2c_time_budget_s=0, reach="spot", init_from=shipped)
    out = run_train(args, progress=False)
    report = (out / "report.md").read_text()
    assert f"warm start from {shipped}" in report and "new inputs, at zero weight: none" in report
    sessions = [onnxruntime.InferenceSession(str(path)) for path in (shipped, out / "policy.onnx")]
    observations = np.random.default_rng(0).normal(size=(8, sessions[0].get_inputs()[0].shape[1])).astype(np.float32)
    before, after = (session.run(None, {"obs": observations}) for session in sessions)
    # One small update away from the file's actor (a fresh network's means are near 0, the hook's are not).
    assert np.abs(before[0]).mean() > 0.2
    assert np.abs(after[0] - before[0]).mean() < 0.1 * np.abs(before[0]).mean()


def test_a_warm_start_from_a_folder_with_no_run_is_refused_before_the_search(tmp_path):
    import pytest

    from punch_trainer.learn.warm_start import WarmStartError
    from punch_trainer.pipelines.train import TrainArgs, run_train

    args = TrainArgs(reward="hook", style="none", out=tmp_path / "run", reach="spot", init_from=tmp_path / "no_run")
    with pytest.raises(WarmStartError, match="neither a finished"):
        run_train(args, progress=False)
    assert not (tmp_path / "run").exists()


def test_fig6_experiment_runs_every_method_with_honest_axes(tmp_path):
    from punch_trainer.pipelines.experiments import METHODS, Fig6Args, fig6

    out, rows = fig6(Fig6Args(reward="straight", seeds=[0], search_iterations=2, a2c_updates=2, characters=4), out=tmp_path)
    assert [r.method for r in rows] == METHODS
    assert (out / "fig6.png").is_file() and (out / "curves.csv").is_file()
    by_method = {r.method: r for r in rows}
    # Matched budgets: every method gets the pretrained variants' total steps (to within one A2C update).
    total = by_method["A2C after pretraining (GAE)"].env_steps
    assert abs(by_method["A2C only"].env_steps - total) <= 4 * 10
    assert abs(by_method["SB3 PPO"].env_steps - total) <= 128
    # Honest axes: the pretrained curves start after the search's own rollouts (2 iterations of 64, plus one).
    import csv

    with open(out / "curves.csv") as handle:
        first = next(r for r in csv.DictReader(handle) if r["method"] == "A2C after pretraining (GAE)")
    assert int(first["env_steps"]) >= (2 * 64 + 1) * 10


def test_pretraining_on_several_datasets(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    from punch_trainer.learn.search import SearchArgs
    from punch_trainer.pipelines.search import run_search

    datasets = []
    for seed in (0, 1):
        out, _, _ = run_search(SearchArgs(out=tmp_path / f"s{seed}", seed=seed, iterations=2, rollouts=16, characters_per_process=16), progress=False)
        datasets.append(out / "dataset.npz")
    punch = Path(sys.executable).with_name("punch")
    result = subprocess.run([punch, "pretrain", *map(str, datasets), "--out", str(tmp_path / "p.onnx"), "--epochs", "100"],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "20 decisions from 2 dataset(s)" in result.stdout and (tmp_path / "p.onnx").is_file()
