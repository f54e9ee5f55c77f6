"""Training over the reach volume: the volume is in the spec, the handshake and every policy's metadata; a
policy trained over it (on a small budget) hits held-out placements more often than a single-spot policy
trained with the same budget, as `punch eval` measures it through PunchController in Godot."""

import json

import numpy as np
import pytest
import torch

from punch_trainer.learn.a2c import collect_episodes
from punch_trainer.learn.policy import SIGMA_MIN, ActorCritic
from punch_trainer.learn.reach import HELD_OUT_SEED, ReachVolume, placement
from punch_trainer.learn.search import SearchArgs
from punch_trainer.learn.volume import STANCE_LEAD_IN_DECISIONS, ConditionSampler, VolumeArgs
from punch_trainer.pipelines.evaluation import EvalArgs, run_eval
from punch_trainer.pipelines.experiments import AfterPunchArgs, after_punch_headroom
from punch_trainer.pipelines.search import run_search
from punch_trainer.pipelines.train import TrainArgs, run_train
from punch_trainer.policy_file import read_policy_metadata
from punch_trainer.reward.rewards import load_reward
from punch_trainer.sim.env import PunchVectorEnv
from punch_trainer.sim.godot import PROJECT_ROOT
from punch_trainer.sim.server import TrainingServer

BUDGET = dict(reward="straight", seed=3, search_iterations=15, search_rollouts=32, pretrain_epochs=600,
              a2c_updates=30, a2c_characters=16, a2c_time_budget_s=0)


@pytest.mark.godot
def test_the_spec_announces_the_reach_volume():
    with TrainingServer(1) as server:
        reach = ReachVolume.from_json(server.info.reach_volume)
    assert reach == ReachVolume((0.6, 0.85), (1.15, 1.55), (-0.25, 0.25), 1.0, True)
    grid = reach.grid((2, 3, 3))
    assert len(grid) == 18 and grid[0].height_m == pytest.approx(1.35) and grid[0].side_m == 0.0


@pytest.mark.godot
@pytest.mark.expensive
def test_a_volume_policy_beats_a_single_spot_policy_on_held_out_placements(tmp_path):
    volume = run_train(TrainArgs(out=tmp_path / "volume", style="none", reach="volume", grid="2,3,3", volume_search_iterations=12,
                                 **BUDGET), progress=False)
    spot = run_train(TrainArgs(out=tmp_path / "spot", style="none", reach="spot", **BUDGET), progress=False)
    with TrainingServer(1) as server:
        announced = ReachVolume.from_json(server.info.reach_volume)
    assert ReachVolume.from_json(read_policy_metadata(volume / "policy.onnx").reach_volume) == announced
    spot_reach = ReachVolume.from_json(read_policy_metadata(spot / "policy.onnx").reach_volume)
    assert spot_reach.is_spot and not spot_reach.any_start_pose

    out, report = run_eval(EvalArgs(policy=volume / "policy.onnx", baseline=spot / "policy.onnx", placements=32,
                                    sigmas=[0.0, 0.3], noisy_episodes=1, search_iterations=3, out=tmp_path / "eval"), progress=False)
    assert report["seed"] == HELD_OUT_SEED and len(report["placements"]) == 32
    for drawn in report["placements"]:
        assert announced.distance_m[0] <= drawn["distance_m"] <= announced.distance_m[1]
    rows = {name: {(r["condition"], r["sigma"]): r for r in e["rows"]}
            for name, e in zip(["volume", "spot"], report["evaluations"], strict=True)}
    for name in rows:
        assert set(rows[name]) == {("every decision", 0.0), ("every decision", 0.3), ("first 4 decisions", 0.3),
                                   ("bag swinging", 0.0), ("after a punch", 0.0)}
    print({name: {f"{k[0]} {k[1]}": (round(r["success_rate"], 3), round(r["return_fraction_of_search_best"], 3))
                  for k, r in table.items()} for name, table in rows.items()})
    # On this budget the volume policy hits about as often as the spot policy at sigma 0 (the spot policy throws
    # its one trained punch at the nearest point of its spot, which often lands, and harder: its return fraction
    # is higher), much more often with a swinging bag, and more often over all conditions. 32 placements put about
    # 3 placements of sampling error on a success rate, and a training this small varies from seed to seed: since
    # the head hangs on its neck, seeds 3, 4 and 5 gave the volume policy -0.03, +0.13 and -0.16 at sigma 0, +0.28,
    # +0.25 and +0.28 with the bag swinging, +0.06, +0.53 and +0.19 at sigma 0.3, and +0.06, +0.27 and +0.20 over
    # all five conditions (seed 3 here); the bounds below hold for all three.
    success = {name: {key: row["success_rate"] for key, row in table.items()} for name, table in rows.items()}
    assert success["volume"][("every decision", 0.0)] >= success["spot"][("every decision", 0.0)] - 0.2
    assert success["volume"][("bag swinging", 0.0)] >= success["spot"][("bag swinging", 0.0)] + 0.15
    mean_success = {name: sum(values.values()) / len(values) for name, values in success.items()}
    assert mean_success["volume"] > mean_success["spot"], mean_success
    for name in ["report.md", "eval.json", "eval_volume.png", "eval_sigma.png"]:
        assert (out / name).is_file(), name
    assert json.loads((out / "eval.json").read_text())["seed"] == HELD_OUT_SEED


@pytest.mark.godot
def test_the_sigma_floor_reaches_the_actions_the_simulator_plays():
    """A policy whose own sigma has shrunk to its minimum plays its mean; with A2C's sigma floor its episodes
    in the simulator carry noise of that sigma, which is what it learns to recover from."""
    reward = load_reward("straight")
    with PunchVectorEnv(1, 16, frames=reward.frames, smoothing_window=3) as env:
        model = ActorCritic(env.info.observation_size, env.info.action_size, seed=0)
        with torch.no_grad():
            model.log_sigma_head.bias.fill_(-20.0)  # clamped to SIGMA_MIN
        spread = {}
        for floor in (0.0, 0.2):
            batch = collect_episodes(model, env, reward, sigma_floor=floor)
            with torch.no_grad():
                mean, _ = model(batch.observations.reshape(-1, env.info.observation_size))
            spread[floor] = float((batch.actions.reshape(mean.shape) - mean).std())
    assert spread[0.0] == pytest.approx(SIGMA_MIN, rel=0.2), spread
    assert spread[0.2] == pytest.approx(0.2, rel=0.1), spread


def test_a_share_of_episodes_at_the_default_placement():
    """`default_share`: that share of A2C episodes has the bag still at the default placement, the rest are
    drawn from the volume as before, and a resumed run draws the same."""
    reach = ReachVolume((0.6, 0.85), (1.15, 1.55), (-0.25, 0.25), 1.0, True)
    default = placement(0.7, 1.35, 0.0)  # a EpisodeConditions, as every drawn one, so equality is a real test
    punches = np.zeros((1, 10, 10), dtype=np.float32)
    draw = ConditionSampler(reach, punches, VolumeArgs(default_share=0.25), seed=5, default_bag=default)
    bags = [bag for update in range(1, 41) for bag in draw(32, update).bags]
    at_default = sum(bag == default for bag in bags) / len(bags)
    assert 0.2 < at_default < 0.3, at_default
    assert draw(32, 7) == draw(32, 7)
    without = ConditionSampler(reach, punches, VolumeArgs(), seed=5, default_bag=default)
    assert not any(bag == default for bag in without(32, 1).bags)
    assert type(without(32, 1).bags[0]) is type(default)


def test_a_share_of_episodes_starts_in_a_stances_guard():
    """`stance_share`: that share of A2C's characters plays a lead-in holding the orthodox or the southpaw guard
    (both drawn), the others a lead-in of zeros (the square guard); none without it."""
    reach = ReachVolume((0.6, 0.85), (1.15, 1.55), (-0.25, 0.25), 1.0, True)
    punches = np.zeros((1, 10, 10), dtype=np.float32)
    guards = np.array([[0.0, -0.667] + [0.1] * 8, [0.0, 0.667] + [0.2] * 8], dtype=np.float32)
    with pytest.raises(ValueError, match="guard actions"):
        ConditionSampler(reach, punches, VolumeArgs(stance_share=0.5), seed=5, default_bag=placement(0.7, 1.35, 0.0))
    draw = ConditionSampler(reach, punches, VolumeArgs(stance_share=0.5), seed=5, default_bag=placement(0.7, 1.35, 0.0),
                            stance_guards=guards)
    lead_ins = np.concatenate([draw(64, update).lead_in for update in range(1, 11)])
    assert lead_ins.shape == (640, STANCE_LEAD_IN_DECISIONS, 10)
    first = lead_ins[:, 0]
    orthodox, southpaw = (np.all(first == guard, axis=1) for guard in guards)
    square = np.all(first == 0.0, axis=1)
    assert np.all(orthodox | southpaw | square) and np.all(lead_ins == lead_ins[:, :1]), "each holds one pose throughout"
    assert 0.4 < (orthodox | southpaw).mean() < 0.6 and 0.4 < orthodox.sum() / (orthodox | southpaw).sum() < 0.6
    assert np.array_equal(draw(64, 3).lead_in, draw(64, 3).lead_in), "a resumed run draws the same"
    without = ConditionSampler(reach, punches, VolumeArgs(), seed=5, default_bag=placement(0.7, 1.35, 0.0))
    assert without(64, 1).lead_in is None


def test_a_policy_for_one_guard_starts_every_episode_there(tmp_path):
    """`punch train --guard orthodox`: the sampler holds that guard alone, in every episode (share 1); the option
    refuses what would mix in other starts, before a simulator starts."""
    reach = ReachVolume((0.6, 0.85), (1.15, 1.55), (-0.25, 0.25), 1.0, True)
    orthodox = np.array([[0.0, -0.667] + [0.1] * 8], dtype=np.float32)
    draw = ConditionSampler(reach, np.zeros((1, 10, 10), dtype=np.float32), VolumeArgs(stance_share=1.0), seed=5,
                            default_bag=placement(0.7, 1.35, 0.0), stance_guards=orthodox)
    lead_ins = np.concatenate([draw(64, update).lead_in for update in range(1, 6)])
    assert np.all(lead_ins == orthodox[0]), "every episode holds the orthodox guard first"
    for wrong in (dict(reach="spot"), dict(search_stances=True), dict(stance_share=0.5)):
        with pytest.raises(ValueError, match="--guard orthodox"):
            run_train(TrainArgs(out=tmp_path / "refused", guard="orthodox", **{**BUDGET, **wrong}), progress=False)
    # A load is drawn from a stance's guard: from the square guard it is refused.
    with pytest.raises(ValueError, match="--load hook draws the arm from a stance's guard"):
        run_train(TrainArgs(out=tmp_path / "refused", load="hook", **BUDGET), progress=False)
    assert not (tmp_path / "refused").exists()


def test_a_nearer_reach_or_other_heights_replace_the_volumes_and_are_refused_when_they_make_no_sense(tmp_path):
    """`punch train --reach-distance NEAR FAR` (a hook's nearer targets): the policy's reach is the server's volume with
    those distances, for a lead hand's move too (not moved forward again); `--reach-height LOW HIGH` (an uppercut's head
    and body) its heights; reversed, one distance, or at a spot, either is refused before a simulator starts."""
    from types import SimpleNamespace

    from punch_trainer.pipelines.train import policy_reach

    info = SimpleNamespace(reach_volume=ReachVolume((0.6, 0.85), (1.15, 1.55), (-0.25, 0.25), 1.0, True).to_json(),
                           stance_lead_forward_m=0.1)
    lead = policy_reach(TrainArgs(guard="southpaw"), info)
    assert lead.distance_m == pytest.approx((0.7, 0.95)) and lead.height_m == (1.15, 1.55)
    hook = policy_reach(TrainArgs(guard="southpaw", reach_distance=[0.7, 0.85]), info)
    assert hook.distance_m == (0.7, 0.85) and hook.side_m == (-0.25, 0.25)
    uppercut = policy_reach(TrainArgs(guard="orthodox", reach_distance=[0.55, 0.7], reach_height=[1.0, 1.55]), info)
    assert (uppercut.distance_m, uppercut.height_m, uppercut.side_m) == ((0.55, 0.7), (1.0, 1.55), (-0.25, 0.25))
    for wrong in (dict(reach_distance=[0.85, 0.7]), dict(reach_distance=[0.7]), dict(reach="spot", reach_distance=[0.7, 0.85])):
        with pytest.raises(ValueError, match="--reach-distance"):
            run_train(TrainArgs(out=tmp_path / "refused", **{**BUDGET, **wrong}), progress=False)
    for wrong in (dict(reach_height=[1.55, 1.0]), dict(reach="spot", reach_height=[1.0, 1.55])):
        with pytest.raises(ValueError, match="--reach-height"):
            run_train(TrainArgs(out=tmp_path / "refused", **{**BUDGET, **wrong}), progress=False)
    assert not (tmp_path / "refused").exists()


def test_lead_ins_start_where_an_earlier_punch_is_mid_way_at_its_end_or_on_the_way_back():
    """`lead_in_every`: every k-th update's characters play a lead-in: a punch played up to a random decision of its
    second half, a whole punch and 1 to 4 decisions of the guard, or the guard alone; all end together."""
    reach = ReachVolume((0.6, 0.85), (1.15, 1.55), (-0.25, 0.25), 1.0, True)
    decisions = 10
    punches = np.arange(1, decisions + 1, dtype=np.float32)[None, :, None].repeat(10, axis=2)  # decision d plays d + 1
    draw = ConditionSampler(reach, punches, VolumeArgs(lead_in_every=2), seed=5, default_bag=placement(0.7, 1.35, 0.0))
    assert draw(8, 1).lead_in is None, "not this update"
    lead_ins = np.concatenate([draw(64, update).lead_in for update in range(2, 42, 2)])
    assert lead_ins.shape == (1280, decisions + 4, 10)
    played = lead_ins[:, :, 0]
    last = [int(row[row > 0][-1]) if (row > 0).any() else 0 for row in played]
    back = [int(np.argmax(row[::-1] > 0)) if (row > 0).any() else -1 for row in played]
    cut_short = [n for n, b in zip(last, back, strict=True) if b == 0 and n < decisions]
    assert cut_short and min(cut_short) >= decisions // 2, "cut in its second half"
    assert {b for b in back if b > 0} == {1, 2, 3, 4}, "on the way back to guard"
    assert 0.35 < last.count(0) / len(last) < 0.55, "the others from the guard"


@pytest.mark.godot
def test_other_moves_punches_are_the_policies_punches_with_either_arm(tmp_path):
    """`--lead-in-policies`: each policy file punches through PunchController and its actions come back with their
    mirror image (the other arm's), held at the guard (zeros) after a shorter punch."""
    from punch_trainer.pipelines.train import other_moves_punches

    with TrainingServer(1) as server:
        reach, mirror = ReachVolume.from_json(server.info.reach_volume), server.info.mirror.actions
    policy = PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx"
    punches = other_moves_punches([policy], reach, 12, mirror, seed=1, placements=2)
    assert punches.shape == (4, 12, 10)
    assert np.allclose(punches[2:], mirror(punches[:2])) and not np.allclose(punches[:2], punches[2:])
    assert np.abs(punches[:2, :5]).max() > 0.1, "a punch, not the guard"
    with pytest.raises(FileNotFoundError, match="no policy file"):
        other_moves_punches([tmp_path / "none.onnx"], reach, 12, mirror, seed=1, placements=2)


@pytest.mark.godot
@pytest.mark.expensive
def test_the_after_punch_experiment_searches_from_both_starts(tmp_path):
    out, _, _ = run_search(SearchArgs(out=tmp_path / "s", reward="straight", iterations=4, rollouts=16,
                                      characters_per_process=16, plateau_iterations=0, seed=7), progress=False)
    rows = after_punch_headroom(AfterPunchArgs(out / "dataset.npz", iterations=3, rollouts=8))
    assert [row.start for row in rows] == ["the guard", "the end of the best punch"]
    assert all(np.isfinite(row.best_return) and 0.0 <= row.last_batch_hit_share <= 1.0 for row in rows)
    # The same search with the same seed from another start: the earlier punch changed what the actions did.
    assert rows[0].best_return != rows[1].best_return
