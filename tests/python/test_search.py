"""Trajectory search: the sigma rule, and small real runs (reproducible, with a complete run directory)."""

import json

import numpy as np
import pytest

from punch_trainer.learn.search import SearchArgs, update_sigma
from punch_trainer.pipelines.search import run_search


def test_sigma_stays_wide_while_nothing_stands_out_and_shrinks_around_a_clear_best():
    rng = np.random.default_rng(0)
    mu, sigma = np.zeros((4, 10)), np.full((4, 10), 0.5)
    samples = mu + sigma * rng.standard_normal((256, 4, 10))
    flat = update_sigma(samples, np.zeros(256), mu, 0.0, sigma, 0.2, 0.02)
    assert np.allclose(flat.mean(), 0.5, atol=0.03), "equal returns keep sigma near the sampling spread"
    # Returns that fall off with distance from mu: good samples cluster at the best, so sigma shrinks.
    returns = -np.linalg.norm((samples - mu).reshape(256, -1), axis=1)
    shrunk = update_sigma(samples, returns, mu, 0.0, sigma, 0.2, 0.02)
    assert shrunk.mean() < 0.5
    assert np.all(shrunk >= 0.8 * sigma - 1e-9), "the clip bounds the change per iteration"
    floor = update_sigma(samples * 0, returns, mu, 0.0, np.full((4, 10), 0.021), 0.2, 0.02)
    assert np.all(floor == 0.02)


@pytest.mark.godot
@pytest.mark.expensive
def test_small_search_is_reproducible_and_writes_its_run(tmp_path):
    args = dict(reward="straight", iterations=4, rollouts=16, characters_per_process=16, plateau_iterations=0, seed=7)
    out, first, report = run_search(SearchArgs(out=tmp_path / "a", **args), progress=False)
    _, second, _ = run_search(SearchArgs(out=tmp_path / "b", **args), progress=False)
    assert first.best_return == second.best_return
    np.testing.assert_array_equal(first.best_actions, second.best_actions)
    assert first.best_return >= first.history[0]["best_return"] - 1e-12 and len(first.history) == 4
    for name in ["config.json", "metrics.csv", "dataset.npz", "report.md", "motion.json", "return.png", "sigma.png", "fist_path.png"]:
        assert (out / name).is_file(), name
    dataset = np.load(out / "dataset.npz")
    assert dataset["observations"].shape == (10, 54) and dataset["actions"].shape == (10, 10)
    assert dataset["features"].shape == (50, 63) and dataset["rewards"].shape == (10,)
    assert float(dataset["return"]) == pytest.approx(first.best_return, rel=1e-6)
    assert json.loads((out / "config.json").read_text())["spec_hash"] == str(dataset["spec_hash"])
    assert report["peak_fist_speed_mps"] > 0


@pytest.mark.godot
@pytest.mark.expensive
def test_a_reward_written_from_scratch_drives_the_search(tmp_path):
    rewards = tmp_path / "my_rewards.py"
    rewards.write_text("def raise_right_fist(f):\n    return {'height': f['fist_r_pos_y'] - 1.5}\n")
    _, result, _ = run_search(SearchArgs(reward=f"{rewards}:raise_right_fist", out=tmp_path / "run", iterations=6,
                                         rollouts=16, characters_per_process=16, plateau_iterations=0), progress=False)
    heights = result.best_features[:, result.feature_names.index("fist_r_pos_y")]
    assert heights.mean() > 1.55, "the search should lift the right fist above its guard height (1.49 m)"


def test_capture_clip_reads_as_a_punch():
    from punch_trainer.capture.bvh import DEFAULT_BVH, captured_punch

    punch = captured_punch(DEFAULT_BVH)
    reach = punch["hand"][-1]
    assert reach[2] == pytest.approx(np.linalg.norm(reach), rel=0.05), "aligned: the reach points forward"
    assert 0.5 < np.linalg.norm(reach) <= 0.62, "scaled: full reach near the character's 0.619 m arm"
    assert 3.0 < float(punch["peak_speed_mps"]) < 12.0


@pytest.mark.godot
@pytest.mark.expensive
def test_baselines_run_on_the_same_environment():
    from punch_trainer.learn.baselines import cem, cma_es
    from punch_trainer.reward.rewards import load_reward
    from punch_trainer.sim.rollouts import RolloutPool

    args = SearchArgs(iterations=3, rollouts=16, characters_per_process=16)
    with RolloutPool(1, 16) as pool:
        for method in (cem, cma_es):
            history = method(args, load_reward("straight"), pool)
            best = [row["best_return"] for row in history]
            assert len(history) == 3 and best == sorted(best), f"{method.__name__}: best return must never fall"
            assert history[-1]["rollouts"] == 48


@pytest.mark.godot
def test_a_search_may_start_from_a_stances_guard():
    """`placement_search(lead_in=...)`: every rollout plays the lead-in first (here the orthodox guard held), so the
    best trajectories start there, and `record_datasets` with the same lead-in records them again exactly (it raises
    otherwise)."""
    from punch_trainer.learn.dataset import record_datasets
    from punch_trainer.learn.reach import placement
    from punch_trainer.learn.search import placement_search
    from punch_trainer.learn.volume import STANCE_LEAD_IN_DECISIONS
    from punch_trainer.reward.rewards import load_reward
    from punch_trainer.sim.rollouts import RolloutPool

    reward = load_reward("straight")
    args = SearchArgs(reward="straight", seed=0, iterations=2, rollouts=8, plateau_iterations=0, characters_per_process=16)
    places = [placement(0.7, 1.35, 0.0), placement(0.75, 1.4, 0.1)]
    with RolloutPool(1, 16) as pool:
        guard = np.array(pool.info.stance_guard_actions["orthodox"], dtype=np.float32)
        lead_in = np.tile(guard, (STANCE_LEAD_IN_DECISIONS, 1))
        results = placement_search(args, reward, pool, progress=False, placements=places, neighbours=0, lead_in=lead_in)
    waist = [np.degrees(r.best_features[0, r.feature_names.index("angle_waist_rotation")]) for r in results]
    assert waist == pytest.approx([-30.0, -30.0], abs=3.0), waist
    datasets = record_datasets(results, reward, args, places, lead_in=lead_in)
    assert len(datasets) == 2 and all(len(d["observations"]) == len(results[0].best_actions) for d in datasets)
