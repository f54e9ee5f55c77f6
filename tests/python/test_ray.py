"""Search and training on a Ray cluster (`--ray`), on a cluster of several nodes simulated on this machine
(`ray.cluster_utils.Cluster`), bound to loopback only: the same seed gives bitwise the same search, dataset
and policy (and `punch eval` the same report) as local processes of the same count and size; a worker killed
and a node removed in the middle of a search are replaced and the search ends as an uninterrupted one; and
every cluster a test starts is shut down by it, leaving no Ray or Godot process behind."""

import json
import os
import time
from pathlib import Path

import numpy as np
import onnx
import pytest
from onnx import numpy_helper

from conftest import godot_processes, ray_processes
from punch_trainer.cli.main import main
from punch_trainer.learn.search import SearchArgs, trajectory_search
from punch_trainer.pipelines.train import TrainArgs, run_train
from punch_trainer.reward.rewards import load_reward
from punch_trainer.sim.cluster import RayTrainingServer, ray_cluster, simulated_cluster
from punch_trainer.sim.godot import ADDON_POLICIES
from punch_trainer.sim.rollouts import RolloutPool

WORKER_NODES = 3
PROCESSES, CHARACTERS = 3, 8


def listening_addresses(pids: set[int]) -> set[str]:
    """The local addresses (hex, as /proc/net/tcp writes them) of the TCP sockets these processes listen on."""
    inodes = set()
    for pid in pids:
        try:
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                target = os.readlink(fd)
                if target.startswith("socket:["):
                    inodes.add(target[8:-1])
        except OSError:
            continue
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for row in Path(table).read_text().splitlines()[1:]:
            columns = row.split()
            if columns[3] == "0A" and columns[9] in inodes:  # 0A: LISTEN
                found.add(columns[1].rsplit(":", 1)[0])
    return found


# 127.0.0.1, ::1 and ::ffff:127.0.0.1, as /proc/net/tcp{,6} write them
LOOPBACK = {"0100007F", "00000000000000000000000001000000", "0000000000000000FFFF00000100007F"}


@pytest.fixture
def cluster():
    """A head node that runs no workers and three worker nodes of 2 CPUs each, all on 127.0.0.1 (`--ray
    simulated:3`); shut down at the end of the test, whatever happened in it, and checked to leave no Ray or
    Godot process."""
    ray_before, godot_before = ray_processes(), godot_processes()
    with simulated_cluster(WORKER_NODES) as simulated:
        yield simulated
    deadline = time.monotonic() + 20
    while ((ray_processes() - ray_before) or (godot_processes() - godot_before)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not ray_processes() - ray_before, "Ray processes left behind by the test's cluster"
    assert not godot_processes() - godot_before, "Godot processes left behind by the test's cluster"


def search(pool: RolloutPool):
    args = SearchArgs(seed=5, iterations=5, rollouts=2 * PROCESSES * CHARACTERS, processes=PROCESSES,
                      characters_per_process=CHARACTERS, smoothing_window=3)
    return trajectory_search(args, load_reward("straight"), pool, progress=False)


@pytest.mark.godot
@pytest.mark.expensive
def test_a_search_on_ray_is_bitwise_the_local_one_with_workers_on_every_node_and_loopback_only(cluster):
    with RolloutPool(PROCESSES, CHARACTERS) as pool:
        local = search(pool)
    with ray_cluster(cluster.address) as backend, RolloutPool(PROCESSES, CHARACTERS, backend=backend) as pool:
        assert all(isinstance(server, RayTrainingServer) for server in pool.servers)
        nodes = {server.node_id for server in pool.servers}
        assert len(nodes) == WORKER_NODES, "the workers should be spread over the worker nodes"
        addresses = listening_addresses(ray_processes())
        assert addresses and addresses <= LOOPBACK, f"Ray listens beyond loopback: {sorted(addresses)}"
        on_ray = search(pool)
    assert on_ray.best_return == local.best_return
    np.testing.assert_array_equal(on_ray.best_actions, local.best_actions)
    assert on_ray.best_slot == local.best_slot


@pytest.mark.godot
@pytest.mark.expensive
def test_a_worker_killed_and_a_node_removed_mid_search_are_replaced_and_the_search_ends_as_an_uninterrupted_one(cluster):
    import ray

    with RolloutPool(PROCESSES, CHARACTERS) as pool:
        reference = search(pool)
    with ray_cluster(cluster.address) as backend, RolloutPool(PROCESSES, CHARACTERS, backend=backend) as pool:
        batches, run = 0, pool.run
        removed: list[str] = []

        def run_then_remove_a_node(*args, **kwargs):
            nonlocal batches
            batches += 1
            if batches == 2:  # a worker dies (its Godot with it)
                ray.kill(pool.servers[1]._actor)
            if batches == 5:  # later in the search: the node of the first worker goes away
                node_id = pool.servers[0].node_id
                node = next(n for n in cluster.worker_nodes if n.node_id == node_id)
                cluster.remove_node(node)
                removed.append(node_id)
            return run(*args, **kwargs)

        pool.run = run_then_remove_a_node
        interrupted = search(pool)
        assert removed and pool.restarts >= 2
        assert removed[0] not in {server.node_id for server in pool.servers}, "a worker is still on the removed node"
    assert interrupted.best_return == reference.best_return
    np.testing.assert_array_equal(interrupted.best_actions, reference.best_actions)


def policy_weights(path: Path) -> list[np.ndarray]:
    return [numpy_helper.to_array(i) for i in sorted(onnx.load(str(path)).graph.initializer, key=lambda i: i.name)]


@pytest.mark.godot
@pytest.mark.expensive
def test_punch_train_with_ray_gives_bitwise_the_local_dataset_and_policy(cluster, tmp_path):
    options = dict(reward="straight", style="none", seed=0, search_iterations=4, search_rollouts=16, processes=2, pretrain_epochs=100, a2c_updates=2,
                   a2c_characters=4, a2c_time_budget_s=0, reach="spot")
    local = run_train(TrainArgs(out=tmp_path / "local", **options), progress=False)  # type: ignore[arg-type]
    arguments = [f"--{key.replace('_', '-')}={value}" for key, value in options.items()]
    assert main(["train", *arguments, f"--out={tmp_path / 'ray'}", "--ray", cluster.address]) == 0
    on_ray = tmp_path / "ray"
    local_data, ray_data = np.load(local / "search" / "dataset.npz"), np.load(on_ray / "search" / "dataset.npz")
    assert sorted(local_data.files) == sorted(ray_data.files)
    for name in local_data.files:
        np.testing.assert_array_equal(ray_data[name], local_data[name], err_msg=name)
    for mine, theirs in zip(policy_weights(on_ray / "policy.onnx"), policy_weights(local / "policy.onnx"), strict=True):
        np.testing.assert_array_equal(mine, theirs)
    summaries = [json.loads((run / "summary.json").read_text()) for run in (local, on_ray)]
    assert summaries[0]["exported_return"] == summaries[1]["exported_return"]


@pytest.mark.godot
@pytest.mark.expensive
def test_punch_eval_with_ray_gives_the_local_report(cluster, tmp_path):
    """The per-placement searches on the workers and the punches through PunchController as Ray tasks (the
    policy's bytes travel, a node need not hold the file): the same figures as a local evaluation."""
    options = ["--policy", str(ADDON_POLICIES / "hook.onnx"), "--placements", "6", "--sigmas", "0,0.3", "--noisy-episodes", "1",
               "--search-iterations", "2"]
    assert main(["eval", *options, "--out", str(tmp_path / "local")]) == 0
    assert main(["eval", *options, "--out", str(tmp_path / "ray"), "--ray", cluster.address]) == 0
    local, on_ray = (json.loads((tmp_path / run / "eval.json").read_text()) for run in ("local", "ray"))
    assert on_ray["search_best"] == local["search_best"]
    assert on_ray["evaluations"] == local["evaluations"]


def test_an_address_where_no_cluster_answers_is_a_clear_error_at_once(tmp_path, capsys):
    started = time.monotonic()
    assert main(["search", "--iterations", "1", "--out", str(tmp_path / "run"), "--ray", "127.0.0.1:1"]) == 1
    assert "no Ray cluster answers at 127.0.0.1:1" in capsys.readouterr().err
    assert time.monotonic() - started < 30 and not (tmp_path / "run").exists()
