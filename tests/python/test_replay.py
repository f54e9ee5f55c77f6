"""`punch replay`: a policy replayed through PunchController in headless Godot, and its parity with the torch
policy in the training server."""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from punch_trainer.errors import GodotRunError, PolicyFileError
from punch_trainer.learn.dataset import load_datasets
from punch_trainer.learn.export import export_policy
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.pretrain import PretrainArgs, pretrain
from punch_trainer.learn.search import SearchArgs
from punch_trainer.learn.volume import success_interval
from punch_trainer.pipelines.evaluation import EvalError, parse_sigmas
from punch_trainer.pipelines.replay import ReplayArgs, ReplayError, policy_metadata, replay_frames, run_replay
from punch_trainer.pipelines.search import run_search
from punch_trainer.reward.rewards import load_reward, score
from punch_trainer.sim.env import PunchVectorEnv
from punch_trainer.sim.godot import ADDON_POLICIES

SMOOTHING_WINDOW = 3
SHIPPED_POLICY = ADDON_POLICIES / "straight.onnx"


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A small straight-punch policy: a short search, pretraining on it, export with the trainer's metadata."""
    root = tmp_path_factory.mktemp("replay")
    out, result, _ = run_search(SearchArgs(out=root / "search", seed=0, iterations=12, rollouts=64, characters_per_process=64,
                                           smoothing_window=SMOOTHING_WINDOW), progress=False)
    data = load_datasets([out / "dataset.npz"])
    model = ActorCritic(data["observations"].shape[1], data["actions"].shape[1])
    pretrain(model, data, PretrainArgs(epochs=600, seed=0), progress=False)
    path = export_policy(model, root / "policy.onnx", contract=data["policy_metadata"], reward="straight",
                         summary={"search_best_return": result.best_return})
    return path, model.eval(), result.best_return


def test_sigmas_parse_as_ranges_or_lists():
    assert parse_sigmas("0.1:0.9:0.1") == pytest.approx([0.1 * i for i in range(1, 10)])
    assert parse_sigmas("0,0.5") == [0.0, 0.5]
    with pytest.raises(EvalError, match="bad --sigmas"):
        parse_sigmas("0.1:x")


@pytest.mark.godot
@pytest.mark.expensive
def test_parity_of_godot_controller_and_torch_policy(trained, tmp_path):
    """Sigma 0: PunchController (ONNX Runtime in Godot) decides what torch decides on the same observations,
    and its punch scores what the torch policy scores in the training server."""
    path, model, _ = trained
    out, rows = run_replay(ReplayArgs(policy=path, sigmas=[0.0], episodes=4, out=tmp_path / "r", keep_frames=True), progress=False)
    meta = json.loads((out / "frames" / "meta.json").read_text())
    record = replay_frames(out / "frames", 0, meta)
    assert record["observations"].shape == (4, 10, 54) and record["features"].shape == (4, 50, 63)
    with torch.no_grad():
        torch_means = model(torch.as_tensor(record["observations"].reshape(-1, 54)))[0].numpy()
    assert np.abs(torch_means - record["mean_actions"].reshape(-1, 10)).max() < 1e-5
    assert np.array_equal(record["actions"], record["mean_actions"]), "sigma 0 adds no noise"
    assert np.all(record["features"] == record["features"][:1]), "every sigma-0 punch is the same punch"

    reward = load_reward("straight")
    torch_return = 0.0
    with PunchVectorEnv(1, 1, smoothing_window=SMOOTHING_WINDOW) as env:
        obs, _ = env.reset()
        for _ in range(10):
            with torch.no_grad():
                mean = model(torch.as_tensor(obs))[0].numpy()
            obs, _, _, _, info = env.step(np.clip(mean, -1, 1))
            torch_return += float(score(reward, info["features"], env.feature_names)[0])
    godot_return = rows[0]["mean_return"]
    # The same bodies and constraints in the same order: the frames agree to about 1e-5 (rounding in how each
    # side composes transforms) until the fist meets the bag, where contact amplifies it (README FAQ).
    print(f'sigma-0 return: Godot {godot_return:.5f}, torch in the training server {torch_return:.5f}')
    assert godot_return == pytest.approx(torch_return, rel=0.01)


@pytest.mark.godot
@pytest.mark.expensive
def test_replay_reports_and_plots_every_sigma(trained, tmp_path):
    path, _, best = trained
    punch = Path(sys.executable).with_name("punch")
    result = subprocess.run([punch, "replay", "--policy", str(path), "--sigmas", "0,0.5", "--episodes", "24",
                             "--noise-decisions", "4", "--out", str(tmp_path / "r")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads((tmp_path / "r" / "replay.json").read_text())
    zero, noisy = report["rows"]
    assert zero["path_spread_m"] == 0.0 and zero["impact_spread_m"] == 0.0
    assert noisy["path_spread_m"] > 0.01, "noise on the first 4 decisions must vary the punches"
    assert zero["return_ratio"] == pytest.approx(zero["mean_return"] / best)
    for name in ("report.md", "replay_returns.png", "replay_paths.png"):
        assert (tmp_path / "r" / name).stat().st_size > 0
    assert not list((tmp_path / "r" / "frames").glob("*.f32")), "raw frames are removed unless --keep-frames"


def test_replay_refuses_bad_policies_clearly(tmp_path):
    with pytest.raises(PolicyFileError, match="not found"):
        run_replay(ReplayArgs(policy=tmp_path / "missing.onnx", sigmas=[0.0], episodes=1), progress=False)
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(b"not a model at all")
    with pytest.raises(PolicyFileError, match="not an ONNX model"):
        run_replay(ReplayArgs(policy=corrupt, sigmas=[0.0], episodes=1), progress=False)
    with pytest.raises(ReplayError, match="sigmas must lie"):
        run_replay(ReplayArgs(policy=SHIPPED_POLICY, sigmas=[1.5], episodes=1), progress=False)


@pytest.mark.godot
@pytest.mark.expensive
def test_a_policy_that_outputs_nan_ends_the_replay_with_an_error(tmp_path, trained):
    """Its punches stop on the error and say so in `punch_finished`; the replay ends at once instead of
    waiting forever for punches that stopped."""
    import onnx
    from onnx import numpy_helper

    model = onnx.load(str(trained[0]))
    for initializer in model.graph.initializer:  # every weight NaN: the real graph, NaN actions
        initializer.CopyFrom(numpy_helper.from_array(np.full(numpy_helper.to_array(initializer).shape, np.nan,
                                                             dtype=np.float32), initializer.name))
    nan_policy = tmp_path / "nan.onnx"
    onnx.save(model, str(nan_policy))
    with pytest.raises((ReplayError, GodotRunError), match="stopped on an error: inference failed: the policy returned NaN"):
        run_replay(ReplayArgs(policy=nan_policy, sigmas=[0.0], episodes=2, timeout_s=120), progress=False)
    assert not list(tmp_path.glob("replay_*")), "a failed replay leaves no folder beside the policy"


def test_a_godot_that_hangs_silently_is_stopped_at_the_deadline(tmp_path, monkeypatch):
    fake = tmp_path / "godot"
    fake.write_text('#!/bin/sh\nfor a in "$@"; do [ "$a" = --version ] && { echo 4.6.3.stable.official; exit 0; }; done\n'
                    "exec sleep 600\n")
    fake.chmod(0o755)
    monkeypatch.setenv("GODOT", str(fake))
    started = time.monotonic()
    with pytest.raises(ReplayError, match="did not finish within 3 s"):
        run_replay(ReplayArgs(policy=SHIPPED_POLICY, sigmas=[0.0], episodes=1, timeout_s=3), progress=False)
    assert time.monotonic() - started < 30


def _protobuf_field(number: int, body: bytes) -> bytes:
    """A length-delimited protobuf field (wire type 2)."""
    def varint(value: int) -> bytes:
        out = bytearray()
        while value >= 0x80:
            out.append((value & 0x7F) | 0x80)
            value >>= 7
        return bytes(out + bytes([value]))
    return varint(number << 3 | 2) + varint(len(body)) + body


def hostile_model_files(directory: Path) -> dict[str, Path]:
    """The issue's bypasses of the model check: the graph written twice (a Loop of 2^40 iterations first,
    which protobuf and ONNX Runtime merge with the real graph), and allowed operators grown to unbounded work
    (Concat of copies to [batch, 16384], an outer product by MatMul to [batch, 16384, 16384])."""
    from onnx import TensorProto, helper

    observations = int(policy_metadata(SHIPPED_POLICY)["punch_observation_size"])

    body = helper.make_graph([helper.make_node("Identity", ["x_in"], ["x_out"]),
                              helper.make_node("Identity", ["cond_in"], ["cond_out"])], "body",
                             [helper.make_tensor_value_info("i", TensorProto.INT64, []),
                              helper.make_tensor_value_info("cond_in", TensorProto.BOOL, []),
                              helper.make_tensor_value_info("x_in", TensorProto.FLOAT, ["batch", observations])],
                             [helper.make_tensor_value_info("cond_out", TensorProto.BOOL, []),
                              helper.make_tensor_value_info("x_out", TensorProto.FLOAT, ["batch", observations])])
    loop = helper.make_graph(
        [helper.make_node("Loop", ["trips", "", "obs"], ["mean"], body=body)], "loop",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", observations])],
        [helper.make_tensor_value_info("mean", TensorProto.FLOAT, ["batch", observations])],
        initializer=[helper.make_tensor("trips", TensorProto.INT64, [], [2**40])])
    shipped = SHIPPED_POLICY.read_bytes()
    files = {"loop_first": _protobuf_field(7, loop.SerializeToString()) + shipped,
             "loop_last": shipped + _protobuf_field(7, loop.SerializeToString())}

    ints = [helper.make_tensor(name, TensorProto.INT64, [len(v)], v)
            for name, v in [("zero", [0]), ("one", [1]), ("ten", [10]), ("axes", [1, 2]), ("last", [2])]]
    growth = helper.make_graph(
        [helper.make_node("Slice", ["obs", "zero", "one", "one"], ["v0"]),
         helper.make_node("Concat", ["v0"] * 128, ["v1"], axis=1),
         helper.make_node("Concat", ["v1"] * 128, ["v2"], axis=1),
         helper.make_node("Unsqueeze", ["v2", "last"], ["column"]),
         helper.make_node("Unsqueeze", ["v2", "one"], ["row"]),
         helper.make_node("MatMul", ["column", "row"], ["square"]),
         helper.make_node("Slice", ["square", "zero", "one", "last"], ["cut"]),
         helper.make_node("Slice", ["cut", "zero", "ten", "one"], ["flat"]),
         helper.make_node("Flatten", ["flat"], ["mean"], axis=1)], "growth",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", observations])],
        [helper.make_tensor_value_info("mean", TensorProto.FLOAT, ["batch", 10])], initializer=ints)
    grown = helper.make_model(growth, opset_imports=[helper.make_opsetid("", 17)])
    helper.set_model_props(grown, policy_metadata(SHIPPED_POLICY))  # otherwise a real policy's
    files["concat_matmul"] = grown.SerializeToString()
    paths = {}
    for name, data in files.items():
        paths[name] = directory / f"{name}.onnx"
        paths[name].write_bytes(data)
    return paths


@pytest.mark.godot
def test_a_hostile_model_file_ends_the_replay_with_one_error_at_once(tmp_path):
    """`punch replay` on a file the model check refuses: one `punch:` error naming the reason, within a short
    deadline (the bypassed check froze the game and hung the replay)."""
    punch = Path(sys.executable).with_name("punch")
    expected = {"loop_first": "graph field more than once", "loop_last": "graph field more than once",
                "concat_matmul": "elements per row, more than the 65536"}
    for name, path in hostile_model_files(tmp_path).items():
        result = subprocess.run([punch, "replay", "--policy", str(path), "--sigmas", "0", "--episodes", "1",
                                 "--characters", "1", "--out", str(tmp_path / name)],
                                capture_output=True, text=True, timeout=120)
        assert result.returncode != 0, name
        errors = [line for line in result.stderr.splitlines() if line.startswith("punch:")]
        assert len(errors) == 1 and "Traceback" not in result.stderr, (name, result.stderr[-2000:])
        assert expected[name] in result.stderr, (name, result.stderr[-2000:])
        assert not (tmp_path / name).exists(), name


def test_the_success_interval_is_wilsons_and_narrows_with_more_punches():
    low, high = success_interval(124, 128)
    assert low < 124 / 128 < high and (round(100 * low, 1), round(100 * high, 1)) == (92.2, 98.8)
    assert success_interval(128, 128)[1] == pytest.approx(1.0) and success_interval(0, 128)[0] == pytest.approx(0.0)
    mirrored = success_interval(4, 128)
    np.testing.assert_allclose(mirrored, (1 - high, 1 - low))
    wide, narrow = success_interval(31, 32), success_interval(496, 512)
    assert narrow[1] - narrow[0] < (wide[1] - wide[0]) / 3
    assert success_interval(0, 0) == (0.0, 1.0)
