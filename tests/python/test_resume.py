"""Interrupted training: a search stopped by Ctrl-C and an A2C run interrupted mid-update leave a consistent
run directory, and resuming it ends exactly where an uninterrupted run ends. A Godot killed during A2C is
restarted without changing the result."""

import copy
import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

from conftest import PROJECT_ROOT
from punch_trainer.learn.a2c import A2CArgs, train_a2c
from punch_trainer.learn.checkpoint import CHECKPOINT_FILE, CheckpointError, load_checkpoint, read_config
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.search import SearchArgs
from punch_trainer.pipelines.search import run_search
from punch_trainer.reward.rewards import load_reward
from punch_trainer.sim.env import PunchVectorEnv

pytestmark = [pytest.mark.godot, pytest.mark.expensive]

# 150 iterations: long enough (about 5 s here) that the test sees its fifth checkpoint and interrupts it before it
# ends; at 40 the search sometimes finished first.
SEARCH_OPTIONS = ["--reward", "straight", "--seed", "3", "--iterations", "150", "--rollouts", "16",
                  "--characters-per-process", "16", "--plateau-iterations", "0"]


def punch(*arguments: str, **kwargs) -> subprocess.Popen:
    # Ctrl-C as a terminal sends it, even where the tests themselves run with SIGINT ignored (a shell's background
    # job), which a child would inherit, and with it ignore the interruption under test.
    return subprocess.Popen([sys.executable, "-m", "punch_trainer.cli.main", *arguments], cwd=PROJECT_ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **kwargs)


REFUSED: list[str] = []
"""why checkpointed_iteration found no checkpoint it could read (mid-write is expected; anything else says why a
test waited in vain)"""


def checkpointed_iteration(run_dir) -> int:
    try:
        state = load_checkpoint(run_dir, "search")
    except CheckpointError as error:
        REFUSED.append(str(error))
        return 0
    return 0 if state is None else state["iteration"]


def test_a_search_stopped_by_ctrl_c_resumes_to_the_uninterrupted_result(tmp_path):
    full = run_search(SearchArgs(seed=3, iterations=150, rollouts=16, characters_per_process=16, plateau_iterations=0,
                                 out=tmp_path / "full"), progress=False)[1]

    cut = tmp_path / "cut"
    process = punch("search", *SEARCH_OPTIONS, "--out", str(cut))
    deadline = time.monotonic() + 120
    while checkpointed_iteration(cut) < 5 and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.02)
    seen = checkpointed_iteration(cut)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, (f"last checkpoint seen: {seen}; refused: {sorted(set(REFUSED))[:5]}", stderr[-2000:])
    assert f"punch search --resume {cut}" in stderr

    # Consistent: the arguments, a whole checkpoint of a finished iteration, no stray temporary file.
    stopped_at = checkpointed_iteration(cut)
    assert 5 <= stopped_at < 150
    assert json.loads((cut / "config.json").read_text())["seed"] == 3
    assert sorted(p.name for p in cut.iterdir()) == ["checkpoint.pt", "config.json"]

    with pytest.raises(CheckpointError, match="--resume"):
        run_search(read_config(cut, SearchArgs), progress=False)
    resumed = punch("search", "--resume", str(cut))
    stdout, stderr = resumed.communicate(timeout=300)
    assert resumed.returncode == 0, stderr
    assert (cut / "report.md").exists()

    metrics = (cut / "metrics.csv").read_text().splitlines()
    assert len(metrics) == 1 + 150
    data = np.load(cut / "dataset.npz")
    reference = np.load(tmp_path / "full" / "dataset.npz")
    np.testing.assert_array_equal(data["actions"], reference["actions"])
    assert f"best return {full.best_return:.4f}" in stdout


class Interrupting:
    """A reward that does something to the run at its n-th call (in the middle of an A2C update)."""

    def __init__(self, reward, at_call: int, action):
        self.reward, self.at_call, self.action, self.calls = reward, at_call, action, 0

    def __call__(self, frames):
        self.calls += 1
        if self.calls == self.at_call:
            self.action()
        return self.reward.function(frames)


def a2c(env, initial, reward, run_dir=None):
    model = copy.deepcopy(initial)
    best, history = train_a2c(model, reward, A2CArgs(updates=4, characters=8, seed=0), env, progress=False, run_dir=run_dir)
    return [h["eval_return"] for h in history] + [h["mean_return"] for h in history[1:]], best.state_dict()


def assert_same_training(result, reference):
    assert result[0] == reference[0]
    for name, tensor in reference[1].items():
        assert torch.equal(result[1][name], tensor), name


def test_a2c_interrupted_mid_update_resumes_and_a_killed_godot_is_restarted(tmp_path):
    straight = load_reward("straight")
    initial = ActorCritic(54, 10, seed=0)
    with PunchVectorEnv(1, 8, frames=50, smoothing_window=3) as env:
        reference = a2c(env, initial, straight)
        per_update = 2 * 10  # an update's episodes and its evaluation: 10 decisions each

        def ctrl_c():
            raise KeyboardInterrupt

        run_dir = tmp_path / "a2c"
        interrupting = dataclasses.replace(straight, function=Interrupting(straight, 1 * 10 + 2 * per_update + 5, ctrl_c))
        with pytest.raises(KeyboardInterrupt):
            a2c(env, initial, interrupting, run_dir)
        assert load_checkpoint(run_dir, "a2c")["update"] == 2
        assert sorted(p.name for p in run_dir.iterdir()) == [CHECKPOINT_FILE]
        assert_same_training(a2c(env, initial, straight, run_dir), reference)

        first_pid = env.servers[0].pid
        killing = dataclasses.replace(straight, function=Interrupting(
            straight, 1 * 10 + 1 * per_update + 3, lambda: os.kill(env.servers[0].pid, signal.SIGKILL)))
        assert_same_training(a2c(env, initial, killing), reference)
        assert env.servers[0].pid != first_pid
