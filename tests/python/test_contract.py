"""The policy contract (punch_core::spec) travels whole from the training server to the game: a policy
written by `punch pretrain` carries the contract of its dataset's episodes, and plays in the game with the
smoothing window it was trained with (before the contract, pretrained policies played with smoothing 1)."""

import json

import numpy as np
import onnxruntime
import pytest

from punch_trainer.cli.main import main
from punch_trainer.learn.search import SearchArgs
from punch_trainer.pipelines.replay import ReplayArgs, policy_metadata, replay_frames, run_replay
from punch_trainer.pipelines.search import run_search
from punch_trainer.sim.env import PunchVectorEnv

pytestmark = [pytest.mark.godot, pytest.mark.expensive]
SMOOTHING_WINDOW = 3
COMPARED_FRAMES = 15  # at most; before any contact: the game and the training server agree to about 1e-5 there
CHARACTER_IMPULSE = slice(18, 21)  # `character_impulse_*`: the character's contact on the bag this frame


def features_in_the_training_server(policy, smoothing_window: int) -> np.ndarray:
    session = onnxruntime.InferenceSession(str(policy), providers=["CPUExecutionProvider"])
    frames = []
    with PunchVectorEnv(1, 1, smoothing_window=smoothing_window) as env:
        obs, _ = env.reset()
        for _ in range(10):
            mean, _ = session.run(None, {"obs": obs.astype(np.float32)})
            obs, _, _, _, info = env.step(np.clip(mean, -1, 1))
            frames.append(info["features"][0])
    return np.concatenate(frames)


def test_a_pretrained_policy_carries_its_contract_and_plays_with_its_smoothing(tmp_path):
    out, _, _ = run_search(SearchArgs(out=tmp_path / "search", seed=1, iterations=4, rollouts=16, characters_per_process=16,
                                      smoothing_window=SMOOTHING_WINDOW), progress=False)
    policy = tmp_path / "pretrained.onnx"
    assert main(["pretrain", str(out / "dataset.npz"), "--out", str(policy), "--epochs", "300"]) == 0

    metadata = policy_metadata(policy)
    contract = json.loads(str(np.load(out / "dataset.npz")["policy_metadata"]))
    assert {k: metadata[k] for k in contract} == contract, "the dataset's whole contract is in the policy"
    assert metadata["punch_smoothing_window"] == str(SMOOTHING_WINDOW) and metadata["punch_frames"] == "50"
    assert metadata["punch_reward"] == "straight"

    replay, _ = run_replay(ReplayArgs(policy=policy, sigmas=[0.0], episodes=1, characters=1, out=tmp_path / "replay",
                                      keep_frames=True), progress=False)
    in_game = replay_frames(replay / "frames", 0, json.loads((replay / "frames" / "meta.json").read_text()))["features"][0]
    smoothed = features_in_the_training_server(policy, SMOOTHING_WINDOW)
    unsmoothed = features_in_the_training_server(policy, 1)
    # Contacts are solved in an order that differs between the two worlds: compare the frames before the first.
    touching = np.flatnonzero((np.abs(in_game[:, CHARACTER_IMPULSE]) + np.abs(smoothed[:, CHARACTER_IMPULSE])).sum(1) > 0)
    compared = min(COMPARED_FRAMES, int(touching[0]) if touching.size else COMPARED_FRAMES)
    assert compared >= 5, f"the punch touched the bag at frame {compared}: too soon to compare"
    agreement = np.abs(in_game[:compared] - smoothed[:compared]).max()
    departure = np.abs(in_game[:compared] - unsmoothed[:compared]).max()
    print(f"game vs training server: smoothing {SMOOTHING_WINDOW} {agreement:.2e}, smoothing 1 {departure:.2e}")
    assert agreement < 1e-3 and departure > 10 * agreement


def test_pretraining_refuses_datasets_of_different_contracts(tmp_path, capsys):
    runs = [run_search(SearchArgs(out=tmp_path / f"s{window}", iterations=1, rollouts=16, characters_per_process=16,
                                  smoothing_window=window), progress=False)[0] for window in (1, 3)]
    assert main(["pretrain", *(str(run / "dataset.npz") for run in runs), "--out", str(tmp_path / "p.onnx")]) == 1
    assert "different policy contracts" in capsys.readouterr().err
