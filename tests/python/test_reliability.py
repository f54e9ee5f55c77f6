"""Faults of the simulator and the trainer: a Godot process killed in the middle of a search is restarted and
the search ends exactly as an uninterrupted one; a trainer killed by SIGKILL leaves no Godot behind."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from conftest import PROJECT_ROOT, godot_processes
from punch_trainer.rewards import load_reward
from punch_trainer.rollouts import RolloutPool
from punch_trainer.search import SearchArgs, trajectory_search

pytestmark = pytest.mark.godot


def search(pool: RolloutPool):
    args = SearchArgs(seed=3, iterations=6, rollouts=32, characters_per_process=16, smoothing_window=3)
    return trajectory_search(args, load_reward("straight"), pool, progress=False)


def test_a_godot_killed_mid_search_is_restarted_and_the_result_is_unchanged():
    with RolloutPool(1, 16) as pool:
        reference = search(pool)
    with RolloutPool(1, 16) as pool:
        batches, run = 0, pool.run

        def run_then_kill(*args, **kwargs):
            nonlocal batches
            batches += 1
            if batches == 4:  # in the middle of the search: kill -9 the simulator before this batch
                os.kill(pool.servers[0].pid, signal.SIGKILL)
            return run(*args, **kwargs)

        pool.run = run_then_kill
        first_pid = pool.servers[0].pid
        interrupted = search(pool)
        assert pool.restarts == 1 and pool.servers[0].pid != first_pid
    assert interrupted.best_return == reference.best_return
    np.testing.assert_array_equal(interrupted.best_actions, reference.best_actions)


def test_a_killed_trainer_leaves_no_godot_behind(tmp_path):
    script = tmp_path / "trainer.py"
    script.write_text(textwrap.dedent("""
        import sys, time
        from punch_trainer.server import TrainingServer
        server = TrainingServer(2)
        print(server.pid, flush=True)
        time.sleep(600)
    """))
    before = godot_processes()
    trainer = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=PROJECT_ROOT)
    godot_pid = int(trainer.stdout.readline())
    assert godot_pid in godot_processes()
    trainer.send_signal(signal.SIGKILL)
    trainer.wait(timeout=10)
    deadline = time.monotonic() + 10
    while godot_pid in godot_processes() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert godot_pid not in godot_processes(), "the Godot of a killed trainer is still running"
    assert godot_processes() <= before
