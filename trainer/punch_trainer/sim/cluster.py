"""Rollout workers on a Ray cluster (`--ray [ADDRESS]` on `punch search`, `train`, `eval`, `bench env`).

`ray_cluster` joins a cluster and yields a `RayBackend`, which the command passes down to whatever starts
training servers. Each worker is a Ray actor that starts a headless Godot training server on its own node (a
local process there, as without Ray) and relays the trainer's messages to it. `RayBackend.start_servers`
hands out one `RayTrainingServer` per worker, in a fixed order: the trainer sends slot p's batch to worker p and reads the
replies in that order, so which node answers first never changes which batch lands in which slot, and a run
on Ray is bitwise the same as one with local processes of the same count and size (a slot gives the same
features in any process of the same size: docs/env.md, Episodes).

A worker that dies, or whose node goes away, surfaces as a `ServerClosedError`: the run's `SimulatorRestarts`
then replaces every worker (Ray places the new ones on the nodes still there) and runs the batch again, as it
does for a local Godot process that crashed. Ray is imported only when `--ray` is given (`pip install
punch-trainer[ray]`); without it the trainer needs no Ray at run time. docs/cluster.md says what a node needs.
"""

from __future__ import annotations

import contextlib
import os
import socket
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from punch_trainer.errors import GodotRunError, PunchError
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.protocol import Message, ServerClosedError, ServerTimeoutError
from punch_trainer.sim.server import ServerConnection, ServerInfo, TrainingServer

WORKER_CPUS = 1.0
"""Ray CPUs a worker (or a task of `RayBackend.map`) asks for; its Godot also runs Jolt's job threads
(docs/cluster.md says how many workers a node takes)"""
START_TIMEOUT_S = 120.0
"""how long a worker may take to be placed and to start its Godot process"""
REPLY_TIMEOUT_S = 120.0
"""how long a reply may take (a local server's reply timeout)"""
INLINE_REPLY_BYTES = 16 << 20
"""replies up to this size go straight back to the trainer in the worker's answer, not through Ray's object
stores (the default limit, 100 kB, sends a 64-character rollout's 0.7 MB through two stores and a transfer)"""
TASK_TIMEOUT_S = 3600.0
"""how long `RayBackend.map` waits for all its tasks"""
SIMULATED = "simulated"
"""`--ray simulated[:NODES]`: a cluster of NODES (default 3) Ray nodes on this machine, on loopback only"""
SIMULATED_NODE_CPUS = 2
LOOPBACK = "127.0.0.1"

T = TypeVar("T")


class RayUnavailableError(PunchError):
    """`--ray` was given but Ray is not installed, or no cluster answered."""


def _ray() -> Any:
    try:
        import ray
    except ImportError:
        raise RayUnavailableError("--ray needs Ray: pip install 'punch-trainer[ray]' (./dev setup installs it)") from None
    return ray


@contextlib.contextmanager
def backend_for(ray_address: str | None) -> Iterator[Backend]:
    """The backend of a command's `--ray` option: `LOCAL` without it (Ray is then never imported), else the
    cluster joined for the block (`ray_cluster`)."""
    if ray_address is None:
        yield LOCAL
        return
    with ray_cluster(ray_address) as backend:
        yield backend


@contextlib.contextmanager
def ray_cluster(address: str) -> Iterator[RayBackend]:
    """Joins the Ray cluster at `address` ('auto': the one `RAY_ADDRESS` names, else one already running on
    this machine; 'simulated[:NODES]': one simulated here for the block) and yields the backend that puts
    training servers and work on it. The connection is closed when the block ends, however it ends, and the
    backend refuses work from then on; a cluster of the user's is left running, a simulated one is shut down."""
    if address.split(":")[0] == SIMULATED:
        with simulated_cluster(int(address.split(":")[1]) if ":" in address else 3) as simulated, ray_cluster(simulated.address) as backend:
            yield backend
        return
    ray = _ray()
    _check_reachable(os.environ.get("RAY_ADDRESS", "") if address == "auto" else address)
    try:
        ray.init(address=address, log_to_driver=False, configure_logging=False, include_dashboard=False)
    except (ConnectionError, RuntimeError, ValueError) as error:
        raise RayUnavailableError(f"no Ray cluster at {address!r}: {error}") from None
    backend = RayBackend(address)
    try:
        yield backend
    finally:
        backend.joined = False
        ray.shutdown()


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fails fast on a HOST:PORT that nothing answers on (Ray itself would keep trying for minutes)."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        return  # 'auto' without RAY_ADDRESS, or a form Ray resolves itself
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as error:
        raise RayUnavailableError(f"no Ray cluster answers at {address} ({error.strerror or error}); "
                                  "start one (docs/cluster.md) or run without --ray") from None


@contextlib.contextmanager
def simulated_cluster(nodes: int) -> Iterator[Any]:
    """A head node that runs no workers and `nodes` worker nodes of `SIMULATED_NODE_CPUS` CPUs each, all on
    127.0.0.1; yields the `ray.cluster_utils.Cluster` (`.address`, `.remove_node`) and shuts it down when the
    block ends, however it ends."""
    if "ray" not in sys.modules:
        # Read when Ray is imported: every node and the driver then take the loopback address, never the
        # machine's own, so nothing of the simulated cluster listens beyond this machine.
        os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    _ray()
    from ray.cluster_utils import Cluster

    cluster: Any = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "node_ip_address": LOOPBACK, "include_dashboard": False})
    try:
        for _ in range(nodes):
            cluster.add_node(num_cpus=SIMULATED_NODE_CPUS, node_ip_address=LOOPBACK)
        cluster.wait_for_nodes()
        yield cluster
    finally:
        cluster.shutdown()


class _Worker:
    """A Ray actor (made remote by `RayBackend`): one local training server on the node it was placed on."""

    def __init__(self, slot_count: int, decision_period: int):
        self.server = TrainingServer(slot_count, decision_period=decision_period, reply_timeout_s=REPLY_TIMEOUT_S)

    def info(self) -> ServerInfo:
        return self.server.info

    def node(self) -> str:
        import ray

        return str(ray.get_runtime_context().get_node_id())

    def request(self, message: Message) -> Message:
        return self.server.request(message)

    def close(self) -> None:
        self.server.close()


class RayTrainingServer(ServerConnection):
    """The trainer's side of one Ray worker: a `ServerConnection` whose requests run on the worker's node."""

    def __init__(self, actor: Any, info: ServerInfo, node_id: str):
        self._actor: Any = actor
        self._pending: Any = None
        self.info = info
        self.last_request_s = time.monotonic()
        self.node_id = node_id
        """the Ray node the worker runs on"""

    def send(self, message: Message) -> None:
        if self._actor is None:
            raise PunchError("the Ray worker is closed")
        self.last_request_s = time.monotonic()
        self._pending = self._actor.request.remote(message)

    def receive(self) -> Message:
        ray = _ray()
        reference, self._pending = self._pending, None
        if reference is None:
            raise PunchError("receive() without a request sent")
        try:
            reply: Message = ray.get(reference, timeout=REPLY_TIMEOUT_S)
        except ray.exceptions.GetTimeoutError:
            raise ServerTimeoutError(f"the Ray worker on node {self.node_id[:12]} did not answer within {REPLY_TIMEOUT_S:.0f} s") from None
        except ray.exceptions.RayTaskError as error:
            # The worker's own error (its Godot process crashed, or the server refused the request): the
            # original exception type, so the run treats it as it would treat a local one.
            raise error.as_instanceof_cause() from None
        except ray.exceptions.RayError as error:
            raise ServerClosedError(f"the Ray worker on node {self.node_id[:12]} was lost ({type(error).__name__})") from None
        return reply

    def close(self) -> None:
        """Stops the worker's Godot process, then the worker. Idempotent; a worker already lost is let go."""
        if self._actor is None:
            return
        ray = _ray()
        actor, self._actor = self._actor, None
        # A worker lost with its node was ended by Ray, and its Godot process died with it (PR_SET_PDEATHSIG).
        with contextlib.suppress(ray.exceptions.RayError):
            ray.get(actor.close.remote(), timeout=10.0)
        ray.kill(actor)


class RayBackend:
    """Training servers as Ray workers, and `map` as Ray tasks, on the cluster joined by `ray_cluster` (made
    only there, and usable only inside its block)."""

    def __init__(self, address: str):
        self.address = address
        self.joined = True
        """False once `ray_cluster`'s block has ended"""
        # SPREAD: workers go to different nodes while there are nodes to go to. No Ray restarts: the run's
        # SimulatorRestarts replaces lost workers itself and reruns the batch.
        self._worker: Any = _ray().remote(num_cpus=WORKER_CPUS, max_restarts=0, scheduling_strategy="SPREAD",
                                          runtime_env={"env_vars": {"RAY_max_direct_call_object_size": str(INLINE_REPLY_BYTES)}})(_Worker)

    @property
    def shares_files(self) -> bool:
        return False

    def _ray(self) -> Any:
        if not self.joined:
            raise RayUnavailableError(f"the Ray cluster at {self.address!r} was left: this backend can start nothing more")
        return _ray()

    def start_servers(self, processes: int, characters_per_process: int, decision_period: int = 5) -> list[ServerConnection]:
        """K workers with N characters each, started together; if one cannot start, all are closed before the
        error propagates (as a `ServerClosedError` when a worker or its node was lost, which a run's restarts
        retry, else as a `GodotRunError`)."""
        ray = self._ray()
        actors = [self._worker.remote(characters_per_process, decision_period) for _ in range(processes)]
        try:
            infos = ray.get([actor.info.remote() for actor in actors], timeout=START_TIMEOUT_S)
            nodes = ray.get([actor.node.remote() for actor in actors], timeout=START_TIMEOUT_S)
            others = {(info.spec_hash, info.extension_version) for info in infos} - {(infos[0].spec_hash, infos[0].extension_version)}
            if others:
                _kill(actors)
                raise GodotRunError(f"the cluster's nodes run different builds (observation spec and extension version: "
                                    f"{(infos[0].spec_hash, infos[0].extension_version)} and {sorted(others)}): run the same "
                                    "commit, set up, on every node (docs/cluster.md)")
            return [RayTrainingServer(actor, info, node) for actor, info, node in zip(actors, infos, nodes, strict=True)]
        except ray.exceptions.GetTimeoutError:
            _kill(actors)
            raise GodotRunError(f"{processes} Ray workers with {WORKER_CPUS:g} CPU each were not all started within "
                                f"{START_TIMEOUT_S:.0f} s: does the cluster have that many CPUs free?", "") from None
        except ray.exceptions.RayActorError as error:
            _kill(actors)
            if error.actor_init_failed:  # its Godot did not start: starting again would fail again
                raise GodotRunError(f"a Ray worker could not start its training server: {error}", str(error)) from None
            raise ServerClosedError(f"a Ray worker was lost while starting ({type(error).__name__})") from None
        except ray.exceptions.RayError as error:
            _kill(actors)
            raise ServerClosedError(f"a Ray worker was lost while starting ({type(error).__name__})") from None

    def map(self, function: Callable[..., T], calls: list[dict[str, Any]]) -> list[T]:
        """Each call a Ray task of one CPU spread over the cluster's nodes, the results in the order of `calls`.
        A task whose node goes away is run again elsewhere by Ray (the functions given here are deterministic,
        so the result is the same); an error raised by `function` is raised here as itself, the other tasks
        cancelled."""
        ray = self._ray()
        task = ray.remote(num_cpus=WORKER_CPUS, scheduling_strategy="SPREAD", max_retries=3)(function)
        references = [task.remote(**call) for call in calls]
        try:
            return list(ray.get(references, timeout=TASK_TIMEOUT_S))
        except BaseException as error:
            for reference in references:
                with contextlib.suppress(Exception):
                    ray.cancel(reference, force=True)
            if isinstance(error, ray.exceptions.GetTimeoutError):
                raise ServerTimeoutError(f"{len(calls)} Ray tasks did not finish within {TASK_TIMEOUT_S:.0f} s") from None
            if isinstance(error, ray.exceptions.RayTaskError):
                raise error.as_instanceof_cause() from None
            if isinstance(error, ray.exceptions.RayError):
                raise ServerClosedError(f"a Ray task was lost ({type(error).__name__}): {error}") from None
            raise


def _kill(actors: list[Any]) -> None:
    ray = _ray()
    for actor in actors:
        ray.kill(actor)
