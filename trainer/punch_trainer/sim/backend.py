"""Where training servers run: the backend a command chooses once and passes down to every pool, env, search
and evaluation it makes.

- `LocalBackend`: headless Godot processes on this machine (the default, `LOCAL`).
- `cluster.RayBackend`: Ray workers on a cluster (`--ray [ADDRESS]`), each a local process on its own node.

A run gives bitwise the same results on either, for the same count and size of servers (docs/cluster.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

from punch_trainer.sim.server import ServerConnection, TrainingServer

T = TypeVar("T")


class Backend(Protocol):
    """Starts training servers and runs independent pieces of work, wherever it puts them."""

    @property
    def shares_files(self) -> bool:
        """Whether the work `map` runs sees this machine's files (a Ray node may not: send bytes instead)."""
        ...

    def start_servers(self, processes: int, characters_per_process: int, decision_period: int = 5) -> list[ServerConnection]:
        """K servers with N characters each, in a fixed order; if one fails to start, the others are closed
        before the error propagates."""
        ...

    def map(self, function: Callable[..., T], calls: list[dict[str, Any]]) -> list[T]:
        """`[function(**call) for call in calls]`, the results in the order of `calls`."""
        ...


@dataclass(frozen=True)
class LocalBackend:
    """Training servers as Godot processes on this machine; `map` runs its calls one after the other here."""

    @property
    def shares_files(self) -> bool:
        return True

    def start_servers(self, processes: int, characters_per_process: int, decision_period: int = 5) -> list[ServerConnection]:
        servers: list[ServerConnection] = []
        try:
            for _ in range(processes):
                servers.append(TrainingServer(characters_per_process, decision_period=decision_period))
        except BaseException:
            for server in servers:
                server.close()
            raise
        return servers

    def map(self, function: Callable[..., T], calls: list[dict[str, Any]]) -> list[T]:
        return [function(**call) for call in calls]


LOCAL = LocalBackend()
"""the backend of every command run without --ray, and of library calls that name none"""
