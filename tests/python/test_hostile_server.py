"""Outsiders against a real run, as real processes against a real training server (second round, issue 32): a
flood of refused hellos stalls nothing and changes nothing, connections held before the trainer connects keep
it out of nothing, and a phase of a run longer than the server's idle timeout fails nothing. The worst an
outsider achieves is being refused."""

import json
import os
import signal
import socket
import struct
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from punch_trainer.learn.search import SearchArgs, trajectory_search
from punch_trainer.pipelines import train as train_pipeline
from punch_trainer.reward.rewards import load_reward
from punch_trainer.sim import server as server_module
from punch_trainer.sim.env import PunchEnv
from punch_trainer.sim.protocol import hello_message
from punch_trainer.sim.rollouts import RolloutPool
from punch_trainer.sim.server import TrainingServer

pytestmark = pytest.mark.godot

# An intruder on the same machine: it knows the port (every user can list it), not the secret.
BAD_HELLOS = textwrap.dedent("""
    import json, socket, struct, sys
    port, count = int(sys.argv[1]), int(sys.argv[2])
    header = json.dumps({"type": "hello", "protocol_version": 4, "secret": "not-the-secret-" * 2}).encode()
    refused = 0
    for _ in range(count):
        with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
            sock.sendall(struct.pack("<II", len(header), 0) + header)
            reply = b""
            while chunk := sock.recv(4096):
                reply += chunk
            refused += b"secret" in reply
    print(refused, flush=True)
""")

HOLD_CONNECTIONS = textwrap.dedent("""
    import socket, sys, time
    port, count = int(sys.argv[1]), int(sys.argv[2])
    held = [socket.create_connection(("127.0.0.1", port), timeout=30) for _ in range(count)]
    print("held", flush=True)
    time.sleep(600)
""")


def small_search(pool: RolloutPool):
    args = SearchArgs(seed=5, iterations=3, rollouts=32, characters_per_process=16, smoothing_window=3)
    return trajectory_search(args, load_reward("straight"), pool, progress=False)


@pytest.fixture(scope="module")
def undisturbed():
    with RolloutPool(1, 16) as pool:
        return small_search(pool)


def test_a_flood_of_refused_hellos_neither_stalls_nor_changes_a_search(undisturbed):
    with RolloutPool(1, 16) as pool:
        intruder = subprocess.Popen([sys.executable, "-c", BAD_HELLOS, str(pool.servers[0].port), "300"],
                                    stdout=subprocess.PIPE, text=True)
        try:
            disturbed = small_search(pool)
            refused, _ = intruder.communicate(timeout=120)
        finally:
            intruder.kill()
        assert int(refused) == 300, "every bad hello is refused"
        # The server is still answering after the whole flood (before the fix it blocked writing its log).
        again = small_search(pool)
        log = pool.servers[0].output.text()
        assert pool.restarts == 0, log
    assert disturbed.best_return == undisturbed.best_return == again.best_return
    np.testing.assert_array_equal(disturbed.best_actions, undisturbed.best_actions)
    # The server logs the first 20 refusals a minute, and counts the rest in one line when the minute ends.
    assert 20 <= log.count("wrong or missing 'secret'") <= 40, log


def test_connections_held_before_the_trainer_connects_keep_it_out_of_nothing(monkeypatch, undisturbed):
    holders: list[subprocess.Popen[str]] = []
    ready = TrainingServer._wait_until_ready

    def held_before_we_connect(self: TrainingServer, timeout_s: float) -> int:
        # Between the server's ready line and the trainer's connection, an outsider takes every slot there is
        # (8 for the run's connections, 16 for connections still to say hello) and more.
        port = ready(self, timeout_s)
        holder = subprocess.Popen([sys.executable, "-c", HOLD_CONNECTIONS, str(port), "30"], stdout=subprocess.PIPE, text=True)
        holders.append(holder)
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        time.sleep(0.2)  # the server accepts them before the trainer's connection
        return port

    monkeypatch.setattr(TrainingServer, "_wait_until_ready", held_before_we_connect)
    try:
        with RolloutPool(1, 16) as pool:
            held = small_search(pool)
            assert pool.restarts == 0
    finally:
        for holder in holders:
            holder.kill()
            holder.wait()
    assert len(holders) == 1, "the first connection got in: no second server was needed"
    assert held.best_return == undisturbed.best_return
    np.testing.assert_array_equal(held.best_actions, undisturbed.best_actions)


@pytest.mark.expensive
def test_a_phase_longer_than_the_servers_idle_timeout_fails_nothing(monkeypatch, capfd, tmp_path):
    idle_timeout_s = 2.0
    monkeypatch.setattr(server_module, "IDLE_TIMEOUT_S", idle_timeout_s)
    pretrain = train_pipeline.pretrain

    def long_pretraining(*args, **kwargs):
        history = pretrain(*args, **kwargs)
        time.sleep(idle_timeout_s + 1.0)  # the A2C servers, started before, quit meanwhile unless replaced
        return history

    monkeypatch.setattr(train_pipeline, "pretrain", long_pretraining)
    args = train_pipeline.TrainArgs(reward="straight", style="none", out=tmp_path / "run", search_iterations=2, search_rollouts=16,
                                    pretrain_epochs=20, a2c_updates=1, a2c_characters=2, a2c_time_budget_s=0, reach="spot")
    out = train_pipeline.run_train(args, progress=False)
    assert (out / "policy.onnx").is_file()
    assert "a Godot process failed" not in capfd.readouterr().err, "no restart: idle servers are replaced before use"


def test_a_gymnasium_env_left_idle_past_its_servers_timeout_starts_the_next_episode(monkeypatch):
    monkeypatch.setattr(server_module, "IDLE_TIMEOUT_S", 1.0)
    with PunchEnv() as env:
        first, _ = env.reset()
        pid = env.server.pid
        time.sleep(1.5)  # the user's own work between episodes: the server quits meanwhile
        again, _ = env.reset()
        assert env.server.pid != pid, "a fresh server"
        np.testing.assert_array_equal(first, again)
        env.step(np.zeros(env.action_space.shape, dtype=np.float32))


@pytest.mark.expensive
def test_a_godot_killed_in_each_train_phase_outside_a2c_is_restarted_and_the_run_unchanged(monkeypatch, capfd, tmp_path):
    """The evaluation after pretraining and the exported policy's run are under the restart rule: a Godot killed
    (SIGKILL) as each starts is restarted, the phase runs again, and the run ends with the same returns."""
    def train(out):
        args = train_pipeline.TrainArgs(reward="straight", style="none", out=out, search_iterations=2, search_rollouts=16,
                                        pretrain_epochs=20, a2c_updates=1, a2c_characters=2, a2c_time_budget_s=0, reach="spot")
        return json.loads((train_pipeline.run_train(args, progress=False) / "summary.json").read_text())

    undisturbed = train(tmp_path / "undisturbed")
    killed = []

    def killing_first(phase):
        def first_call_killed(*args, **kwargs):
            env = next(a for a in args if hasattr(a, "servers"))
            if phase not in killed:
                killed.append(phase)
                os.kill(env.servers[0].pid, signal.SIGKILL)
            return phase(*args, **kwargs)
        return first_call_killed

    for name in ("evaluate_noise_free", "run_exported_policy"):
        monkeypatch.setattr(train_pipeline, name, killing_first(getattr(train_pipeline, name)))
    capfd.readouterr()
    disturbed = train(tmp_path / "disturbed")
    assert len(killed) == 2
    assert capfd.readouterr().err.count("a Godot process failed") == 2
    for key in ("pretrained_return", "exported_return"):
        assert disturbed[key] == undisturbed[key], key


def resident_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError(f"no VmRSS for process {pid}")


def test_seven_clients_with_the_secret_keep_the_server_within_its_memory_budget():
    """Seven connections of the run each send a 200 MB message and stay (before the fix, the buffers kept that
    memory after the message was answered and took the real server to 1.5 GB): the server stays within its
    documented 512 MiB for connections, and the run's own connection goes on."""
    with TrainingServer(1) as server:
        start = resident_mb(server.pid)
        header = json.dumps({"type": "hoard", "arrays": [{"name": "a", "shape": [50_000_000]}]}).encode()
        message = struct.pack("<II", len(header), 200_000_000) + header + bytes(200_000_000)
        clients, answered = [], 0
        for _ in range(7):
            client = socket.create_connection(("127.0.0.1", server.port), timeout=30)
            client.sendall(hello_message(server.secret).encode())
            assert b"hello" in client.recv(65536)
            clients.append(client)
            try:
                client.sendall(message)
                answered += b"error" in client.recv(65536)
            except OSError:  # closed by the server: its budget is full
                pass
        peak = resident_mb(server.pid)
        server.rollout(np.zeros((1, 10, 10), np.float32), smoothing_window=3)
        for client in clients:
            client.close()
    assert answered >= 1
    assert peak - start < 512 + 64, f"the server grew from {start:.0f} MB to {peak:.0f} MB ({answered} messages answered)"
