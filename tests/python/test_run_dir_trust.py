"""A run directory is checked before it is trusted: a resume runs no code the command line did not name,
refuses a checkpoint that is another run's, edited or damaged, and refuses values no run writes (negative
iterations, NaN, wrong shapes), each as one `punch:` line. No Godot: every case is refused before a
simulator would start, or tested on the restore functions the pipelines call."""

import dataclasses
import hashlib
import io
import json
import shutil

import numpy as np
import pytest
import torch

from punch_trainer.cli.main import main
from punch_trainer.learn.a2c import A2CArgs, restore_a2c
from punch_trainer.learn.checkpoint import (
    CHECKPOINT_FILE,
    CONFIG_FILE,
    CheckpointError,
    load_checkpoint,
    read_config,
    save_checkpoint,
    write_config,
)
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.search import SearchArgs, restore_search

DECISIONS, ACTIONS, FEATURES = 10, 10, 60
SHAPE = (1, DECISIONS, ACTIONS)


def search_state(iteration: int = 3) -> dict:
    """What trajectory_search checkpoints after `iteration` iterations of one placement."""
    rng = np.random.default_rng(0)
    rng.standard_normal(5)
    history = [{"iteration": i, "rollouts": 1 + 16 * i, "elapsed_s": 0.1 * i, "best_return": 1.0, "mean_return": 0.5,
                "sigma_mean": 0.9, "best_forward": 1.0} for i in range(1, iteration + 1)]
    return {"iteration": iteration, "mu": np.zeros(SHAPE, np.float32), "sigma": np.full(SHAPE, 0.9),
            "rng_state": rng.bit_generator.state,
            "bests": [{"actions": np.zeros((DECISIONS, ACTIONS), np.float32), "executed": np.zeros((DECISIONS, ACTIONS), np.float32),
                       "return": 1.0, "features": np.zeros((50, FEATURES), np.float32), "terms": {"forward": 1.0}, "slot": 0}],
            "history": history, "rollouts": 1 + 16 * iteration, "last_improvement": 1, "elapsed_s": 0.3, "stopped": False}


def new_run(path, seed=3, reward="straight", **extra):
    args = SearchArgs(reward=reward, seed=seed, iterations=40, rollouts=16, out=path)
    write_config(path, args, frames=50, reward_fingerprint=f"preset:{reward}", **extra)
    return args


def restore(run_dir, args):
    saved = load_checkpoint(run_dir, "search")
    return restore_search(saved, args, np.random.default_rng(args.seed), SHAPE, FEATURES, ["f"] * FEATURES, 16)


def resign(path, edit):
    """A tamperer who knows the format: edits the state and writes a valid checksum."""
    data = path.read_bytes()
    header, _, body = data.partition(b"\n")
    saved = torch.load(io.BytesIO(body), weights_only=True)
    edit(saved["state"])
    buffer = io.BytesIO()
    torch.save(saved, buffer)
    body = buffer.getvalue()
    path.write_bytes(header[:-64] + hashlib.sha256(body).hexdigest().encode() + b"\n" + body)


def test_an_untouched_checkpoint_restores(tmp_path):
    args = new_run(tmp_path)
    save_checkpoint(tmp_path, "search", search_state())
    mu, sigma, bests, history, counters = restore(tmp_path, args)
    assert counters == (3, 49, 1, 0.3, False) and len(history) == 3 and bests[0].best_return == 1.0


def two(state, key, value):
    state[key] = value


TAMPERED = {
    "negative iterations": (lambda s: two(s, "iteration", -5), "iteration is -5"),
    "iterations past the run's": (lambda s: two(s, "iteration", 41), "iteration is 41"),
    "iteration as text": (lambda s: two(s, "iteration", "3"), "iteration is '3'"),
    "stopped as a number": (lambda s: two(s, "stopped", 1), "stopped is 1"),
    "infinite elapsed time": (lambda s: two(s, "elapsed_s", float("inf")), "elapsed_s is inf"),
    "NaN in the table": (lambda s: s["mu"].__setitem__((0, 0, 0), float("nan")), "mu holds values"),
    "table of another shape": (lambda s: two(s, "mu", torch.zeros(2, 3)), "mu is"),
    "negative sigma": (lambda s: s["sigma"].__setitem__((0, 0, 0), -1.0), "sigma holds values"),
    "history cut short": (lambda s: s["history"].pop(), "history does not hold"),
    "history as a dict": (lambda s: two(s, "history", {"a": 1}), "history does not hold"),
    "a best's return NaN": (lambda s: s["bests"][0].__setitem__("return", float("nan")), "return is nan"),
    "a best's slot outside the process": (lambda s: s["bests"][0].__setitem__("slot", 99), "slot is 99"),
    "bests missing": (lambda s: two(s, "bests", []), "holds 0 bests"),
    "random state garbage": (lambda s: two(s, "rng_state", {"bit_generator": "nonsense"}), "not what a search writes"),
    "a key missing": (lambda s: s.pop("last_improvement"), "last_improvement is None"),
}


@pytest.mark.parametrize("case", list(TAMPERED))
def test_tampered_values_with_a_valid_checksum_are_refused(tmp_path, case):
    edit, message = TAMPERED[case]
    args = new_run(tmp_path)
    save_checkpoint(tmp_path, "search", search_state())
    resign(tmp_path / CHECKPOINT_FILE, edit)
    with pytest.raises(CheckpointError, match=message):
        restore(tmp_path, args)


def test_an_edited_or_truncated_or_old_checkpoint_is_refused(tmp_path):
    new_run(tmp_path)
    save_checkpoint(tmp_path, "search", search_state())
    path = tmp_path / CHECKPOINT_FILE
    data = bytearray(path.read_bytes())
    data[-100] ^= 1
    path.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="does not match its checksum"):
        load_checkpoint(tmp_path, "search")
    path.write_bytes(bytes(data[:len(data) // 2]))
    with pytest.raises(CheckpointError, match="does not match its checksum"):
        load_checkpoint(tmp_path, "search")
    torch.save({"version": 1, "kind": "search", "state": {"iteration": 40, "stopped": True}}, path)  # the old format
    with pytest.raises(CheckpointError, match="not a version-2 punch checkpoint"):
        load_checkpoint(tmp_path, "search")
    path.write_bytes(b"")
    with pytest.raises(CheckpointError):
        load_checkpoint(tmp_path, "search")


@pytest.mark.parametrize("other, message", [
    ({"seed": 4}, "its seed differs"),
    ({"reward": "hook"}, "its reward differs"),
    ({}, "its run differs"),  # the same arguments, another run
])
def test_a_checkpoint_of_another_run_is_refused(tmp_path, other, message):
    theirs, ours = tmp_path / "theirs", tmp_path / "ours"
    new_run(theirs, **({"seed": other["seed"]} if "seed" in other else {}), **({"reward": other["reward"]} if "reward" in other else {}))
    save_checkpoint(theirs, "search", search_state())
    new_run(ours)
    shutil.copy(theirs / CHECKPOINT_FILE, ours / CHECKPOINT_FILE)
    with pytest.raises(CheckpointError, match=message):
        load_checkpoint(ours, "search")


def test_a_finished_search_rewriting_its_config_keeps_its_checkpoint_resumable(tmp_path):
    """The search's last config.json (with the spec hash and the clip it used) still owns its checkpoints."""
    args = new_run(tmp_path)
    save_checkpoint(tmp_path, "search", search_state())
    write_config(tmp_path, args, frames=50, spec_hash="abc", clip_epsilon=0.2)
    assert json.loads((tmp_path / CONFIG_FILE).read_text())["reward_fingerprint"] == "preset:straight"
    assert load_checkpoint(tmp_path, "search")["iteration"] == 3


def test_a2c_checkpoint_values_are_checked(tmp_path):
    model = ActorCritic(8, 10, seed=0)
    optimizer = torch.optim.Adam(model.parameters())
    state = {"update": 2, "model": model.state_dict(), "optimizer": optimizer.state_dict(), "best_model": model.state_dict(),
             "best_eval": 1.0, "best_episode_return": 2.0, "history": [{}, {}, {}], "elapsed_s": 1.0, "stopped": False,
             "torch_rng_state": torch.get_rng_state()}
    args = A2CArgs(updates=5)
    assert restore_a2c(state, model, optimizer, args)[4] == (2, 1.0, False)
    bad_parameters = {k: v.clone() for k, v in model.state_dict().items()}
    next(iter(bad_parameters.values())).view(-1)[0] = float("nan")
    for key, value, message in [("update", -1, "update is -1"), ("update", 6, "update is 6"),
                                ("best_model", bad_parameters, "not finite"), ("history", [{}], "history"),
                                ("torch_rng_state", torch.zeros(3), "random state"), ("optimizer", {"state": 1}, "not what A2C writes"),
                                ("model", {"nonsense": torch.zeros(1)}, "not what A2C writes")]:
        with pytest.raises(CheckpointError, match=message):
            restore_a2c({**state, key: value}, model, optimizer, args)


BAD_CONFIGS = {
    "negative seed": ({"seed": -1}, "seed -1: must be at least 0"),
    "iterations as text": ({"iterations": "many"}, "iterations 'many': must be a whole number"),
    "absurd iterations": ({"iterations": 10**9}, "iterations 1000000000: must be at least 1, at most 100000"),
    "NaN sigma": ("NaN", "NaN is not a number"),
    "a list": ([1, 2], "holds a list"),
    "truncated": ('{"seed": 3', "cannot read"),
    "reward missing its type": ({"reward": 5}, "reward 5: must be text"),
    "float iterations": ({"iterations": 4.5}, "must be a whole number"),
}


@pytest.mark.parametrize("case", list(BAD_CONFIGS))
def test_a_tampered_config_is_one_punch_line(tmp_path, capsys, case):
    edit, message = BAD_CONFIGS[case]
    new_run(tmp_path)
    config = json.loads((tmp_path / CONFIG_FILE).read_text())
    if isinstance(edit, dict):
        (tmp_path / CONFIG_FILE).write_text(json.dumps({**config, **edit}))
    elif edit == "NaN":
        (tmp_path / CONFIG_FILE).write_text(json.dumps(config).replace('"sigma_init": 1.0', '"sigma_init": NaN'))
    else:
        (tmp_path / CONFIG_FILE).write_text(edit if isinstance(edit, str) else json.dumps(edit))
    assert main(["search", "--resume", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("punch: ") and err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err


def test_a_resume_runs_no_code_the_command_line_did_not_name(tmp_path, capsys):
    marker = tmp_path / "ran"
    evil = tmp_path / "evil.py"
    evil.write_text(f"open({str(marker)!r}, 'w').close()\ndef reward(f):\n    return f['fist_r_vel_z']\n")
    run = tmp_path / "run"
    new_run(run)
    config = json.loads((run / CONFIG_FILE).read_text())
    (run / CONFIG_FILE).write_text(json.dumps({**config, "reward": f"{evil}:reward"}))
    assert main(["search", "--resume", str(run)]) == 1
    err = capsys.readouterr().err
    assert "a resume runs only code the command line names" in err and f"--reward {evil}:reward" in err
    assert main(["search", "--resume", str(run), "--reward", "hook"]) == 1
    assert "not 'hook'" in capsys.readouterr().err
    assert not marker.exists()
    # Named on the command line, it runs (in its worker) and its source is checked against the run's.
    assert main(["search", "--resume", str(run), "--reward", f"{evil}:reward"]) == 1
    err = capsys.readouterr().err
    assert "is not the code" in err and "fingerprint" in err, err
    assert marker.exists()


def test_search_and_train_options_read_back_are_checked(tmp_path):
    args = new_run(tmp_path)
    assert read_config(tmp_path, SearchArgs) == dataclasses.replace(args, out=tmp_path, frames=50)


def test_a_train_resume_runs_no_code_the_command_line_did_not_name(tmp_path, capsys):
    from punch_trainer.pipelines.train import TrainArgs

    marker = tmp_path / "ran"
    evil = tmp_path / "evil.py"
    evil.write_text(f"open({str(marker)!r}, 'w').close()\ndef reward(f):\n    return f['fist_r_vel_z']\n")
    run = tmp_path / "run"
    write_config(run, TrainArgs(reward=f"{evil}:reward", out=run))
    assert main(["train", "--resume", str(run)]) == 1
    assert "a resume runs only code the command line names" in capsys.readouterr().err
    assert not marker.exists()
