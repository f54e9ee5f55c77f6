"""PunchController in a game: trained policies played batched in an ordinary scene, and every fault a game can
throw at it answered with a clear error (or a clamp) while the game goes on."""

import json

import numpy as np
import pytest
import torch

from punch_trainer.cli.replay import policy_metadata
from punch_trainer.cli.train import TrainArgs, run_train
from punch_trainer.learn.export import export_onnx
from punch_trainer.sim.godot import GODOT_PROJECT, PROJECT_ROOT, run_godot

pytestmark = pytest.mark.godot
FIXTURES = PROJECT_ROOT / "tests" / "fixtures"


@pytest.fixture(scope="module")
def policy(tmp_path_factory):
    out = run_train(TrainArgs(reward="straight", out=tmp_path_factory.mktemp("game") / "run", search_iterations=30,
                              search_rollouts=64, pretrain_epochs=800, a2c_updates=1, a2c_characters=4,
                              a2c_time_budget_s=None), progress=False)
    return out / "policy.onnx"


def run_script(name: str, *args: str):
    script = PROJECT_ROOT / "tests" / "godot" / name
    return run_godot(["--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), "--script", str(script), "--", *args],
                     check=False, timeout_s=120)


def test_punch_controllers_play_a_shared_policy_batched_in_a_game_scene(policy):
    run = run_script("punch_scene.gd", f"--policy={policy}")
    assert run.fatal_lines() == [] and "ERROR" not in run.log, run.log[-3000:]
    line = next(line for line in run.log.splitlines() if line.startswith("PUNCH_SCENE "))
    report = json.loads(line[len("PUNCH_SCENE "):])
    assert report["started"] == 6 and len(report["finished"]) == 6, run.log[-3000:]
    first_round, second_round = report["finished"][:3], sorted(report["finished"][3:], key=lambda m: m["pair"])
    for finished in first_round:
        assert finished["frames"] == 50 and finished["hits"] >= 1, "every punch should reach its bag"
        assert 3.0 < finished["peak_fist_speed_mps"] < 15.0
        # No noise: alike, though not bitwise, as each sits at other world coordinates.
        assert finished["peak_fist_speed_mps"] == pytest.approx(first_round[0]["peak_fist_speed_mps"], rel=0.05)
    assert {hit[0] for hit in report["hits"]} == {0, 1, 2}
    # Second round, against still-swinging bags: pairs 0 and 2 punch alike again, while sigma raised on pair 1
    # in the middle of its punch takes effect at its next decision and makes its punch depart from theirs.
    noise_free, noisy, control = second_round
    print("second round (peak fist speed, strongest hit):", [(m["peak_fist_speed_mps"], m["strongest_hit_ns"]) for m in second_round])
    assert noise_free["peak_fist_speed_mps"] == pytest.approx(control["peak_fist_speed_mps"], rel=0.01)
    assert abs(noisy["peak_fist_speed_mps"] - noise_free["peak_fist_speed_mps"]) > 0.1 or \
        abs(noisy["strongest_hit_ns"] - noise_free["strongest_hit_ns"]) > 0.1 * noise_free["strongest_hit_ns"], second_round
    # One ONNX Runtime call per decision tick for all three controllers.
    assert (report["inference"]["calls"], report["inference"]["rows"]) == (10, 30)


def nan_policy(path, contract: dict[str, str]):
    class NanActor(torch.nn.Module):
        def forward(self, obs):
            mean = obs[:, :10] * torch.tensor(float("nan"))
            return mean, torch.ones_like(mean)

    return export_onnx(NanActor(), 45, path, metadata=contract, verify=False)


def test_controller_faults_give_clear_errors_and_the_game_goes_on(policy, tmp_path):
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(np.random.default_rng(0).bytes(3000))
    contract = policy_metadata(policy)
    nan = nan_policy(tmp_path / "nan.onnx", contract)
    incomplete = nan_policy(tmp_path / "incomplete.onnx", {k: v for k, v in contract.items() if k != "punch_smoothing_window"})
    run = run_script("controller_faults.gd", f"--policy={policy}", f"--nan-policy={nan}", f"--corrupt={corrupt}",
                     f"--tiny={FIXTURES / 'tiny_actor.onnx'}", f"--pck={tmp_path / 'game.pck'}", f"--incomplete={incomplete}")
    assert run.fatal_lines() == [], run.log[-3000:]
    line = next((line for line in run.log.splitlines() if line.startswith("FAULTS ")), None)
    assert line, f"the game did not reach its end:\n{run.log[-3000:]}"
    report = json.loads(line[len("FAULTS "):])
    assert report["refused"] == {"missing": True, "corrupt": True, "incompatible": True, "empty": True,
                                 "wrong_decision_period": True, "good_policy_afterwards_punches": True}
    for message in ["policy file not found", "invalid ONNX model", "incompatible policy '", "no policy file set",
                    "incompatible policy: it was trained for spec", "returned NaN", "the target was freed",
                    "the character was freed", "noise_sigma 5 is outside 0..1; using 1"]:
        assert message in run.log, message
    assert report["nan_started"] and report["nan_stopped"]
    # A policy without the whole contract is refused, naming the missing key and how to re-export.
    assert report["incomplete_refused"]
    assert "has no 'punch_smoothing_window' metadata; export it again with `punch train` or `punch pretrain`" in run.log
    assert report["target_freed_stopped"] and report["character_freed_stopped"]
    assert report["sigma_after_set"] == [1.0, 0.0, 0.0, 0.25]
    assert report["pck_mounted"] and report["pck_started"] and report["pck_punch"]["frames"] == 50


def test_a_character_facing_any_way_punches_as_it_does_facing_forward(policy):
    """Turned by 90, -90, 180, 37 and -150 degrees and moved, each with its sandbag in front of it, a character
    playing the policy with no noise senses the same features as the one at the origin facing +Z (in its own
    frame) and hits its bag alike. Before joint angles were read in the character's frame, every turned
    character missed."""
    run = run_script("turned_scene.gd", f"--policy={policy}")
    assert run.fatal_lines() == [] and "ERROR" not in run.log, run.log[-3000:]
    line = next(line for line in run.log.splitlines() if line.startswith("TURNED_SCENE "))
    punches = json.loads(line[len("TURNED_SCENE "):])
    assert len(punches) == 6, run.log[-3000:]
    reference = next(p for p in punches if p["yaw"] == 0.0)
    features = np.array(reference["features"]).reshape(50, -1)
    for punch in punches:
        turned = np.array(punch["features"]).reshape(50, -1)
        # Relative to the feature's size: float32 world coordinates 30 m from the origin round joint speeds of
        # tens of rad/s at about 1e-4 of their size.
        before_contact = (np.abs(turned[:25] - features[:25]) / (1.0 + np.abs(features[:25]))).max()
        print(f"yaw {punch['yaw']:6.1f}: hits {punch['hits']}, peak {punch['peak_fist_speed_mps']:.3f} m/s, "
              f"largest relative feature difference over the first 25 frames {before_contact:.2e}")
        assert punch["hits"] >= 1, punch["yaw"]
        assert before_contact < 1e-3, punch["yaw"]
        assert punch["peak_fist_speed_mps"] == pytest.approx(reference["peak_fist_speed_mps"], rel=0.02)

