"""A headless Godot training server process and the connection to it. The trainer starts and stops these
itself: the server picks a free port and prints it, the client handshakes and checks versions, every wait
has a timeout, and the process is killed by its own PID on close."""

from __future__ import annotations

import os
import secrets
import socket
import subprocess
import time
from dataclasses import dataclass
from typing import Self

import numpy as np

from punch_trainer.errors import GodotRunError, PunchError
from punch_trainer.framing import write_frame
from punch_trainer.sim.conditions import EpisodeConditions
from punch_trainer.sim.godot import GODOT_PROJECT, start_godot, stop_godot
from punch_trainer.sim.godot_output import GodotOutput
from punch_trainer.sim.mirror import MirrorRules
from punch_trainer.sim.protocol import (
    PROTOCOL_VERSION,
    Bags,
    Message,
    ServerClosedError,
    ServerError,
    close_message,
    hello_message,
    receive,
    reset_message,
    rollout_message,
    step_message,
)

SERVER_SCENE = "res://training/training_server.tscn"
SECRET_VARIABLE = "PUNCH_SERVER_SECRET"
"""carries a server's secret to it: in its environment, which other users cannot read (a command line they can)"""
READY_PREFIX = "PUNCH_SERVER_READY "
IDLE_TIMEOUT_S = 120.0
"""a server quits after this long without a request (so none outlives a trainer that lost it); the trainer
replaces one idle for most of it before using it again (`ServerConnection.idle_expired`)"""
CONNECT_ATTEMPTS = 5
"""connections the trainer tries while its server says it is busy (others hold its connections)"""


class ProtocolVersionError(PunchError):
    """The server speaks another protocol version."""


class ServerBusyError(PunchError):
    """The server refused the trainer's connection because its connections were taken (by other processes)."""


@dataclass(frozen=True)
class ServerInfo:
    """What the server said in its handshake: the policy spec (defined once, in punch_core::spec) and the
    server's own settings."""

    slot_count: int
    decision_period: int
    physics_hz: int
    spec_hash: str
    spec_version: int
    extension_version: str
    action_names: list[str]
    action_lower_rad: list[float]
    action_upper_rad: list[float]
    observation_names: list[str]
    feature_names: list[str]
    default_bag: EpisodeConditions
    """where the bag hangs unless a reset says otherwise"""
    reach_volume: dict[str, object]
    """the target placements training covers by default (punch_core::spec::REACH_VOLUME)"""
    mirror: MirrorRules
    """how features, observations, actions and episode conditions mirror, left for right (punch_core::contract::mirror)"""
    stance_guard_actions: dict[str, list[float]]
    """the action that holds each boxing stance's guard, by stance name (`orthodox`, `southpaw`;
    punch_core::contract::stance)"""
    loaded_guard_actions: dict[str, dict[str, list[float]]]
    """each stance's guard with the punching (right) arm in a move's load, by stance and load name (`hook`,
    `uppercut`; punch_core::contract::stance::Load)"""
    stance_lead_forward_m: float
    """how much further forward than the reach volume's a lead hand's targets lie in the stance (m; its guard holds the
    lead fist that much nearer: punch_core::contract::stance::LEAD_REACH_FORWARD_M)"""

    @property
    def observation_size(self) -> int:
        return len(self.observation_names)

    @property
    def action_size(self) -> int:
        return len(self.action_names)


class ServerConnection:
    """What the trainer asks of a training server, wherever it runs: `TrainingServer` (a local process) or
    `cluster.RayTrainingServer` (a process on a Ray worker node). Subclasses send and receive."""

    info: ServerInfo
    idle_timeout_s: float = IDLE_TIMEOUT_S
    """the server quits after this long without a request"""
    last_request_s: float = 0.0
    """time.monotonic() of the last request sent (or of the start)"""

    def idle_expired(self, share: float = 0.8) -> bool:
        """Whether this server has had no request for `share` of its idle timeout or more: it may have quit, or
        may quit before the next reply, so it should be replaced before an episode starts."""
        return time.monotonic() - self.last_request_s >= share * self.idle_timeout_s

    def send(self, message: Message) -> None:
        raise NotImplementedError

    def receive(self) -> Message:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def request(self, message: Message) -> Message:
        self.send(message)
        return self.receive()

    def reset(self, frames: int = 50, bags: Bags = None, smoothing_window: int = 1, lead_in: np.ndarray | None = None) -> Message:
        """A new episode for every slot (after the `lead_in` actions, if any: `reset_message`). The reply holds
        `observations` [N, O], `features` [N, F] and the `policy_metadata` that a policy trained on such
        episodes must carry."""
        return self.request(reset_message(frames, bags=bags, smoothing_window=smoothing_window, lead_in=lead_in))

    def step(self, actions: np.ndarray) -> Message:
        """One decision of actions [N, A]; the reply holds its `features` [N, period, F] and the next
        `observations`."""
        return self.request(step_message(actions))

    def rollout_reply(self, actions: np.ndarray, bags: Bags = None, smoothing_window: int = 1) -> Message:
        """Open loop: raw actions [N, decisions, A] from the initial state. The reply holds `features`
        [N, frames, F] and `executed_actions` [N, decisions, A] (after smoothing)."""
        return self.request(rollout_message(actions, bags=bags, smoothing_window=smoothing_window))

    def rollout(self, actions: np.ndarray, bags: Bags = None, smoothing_window: int = 1) -> np.ndarray:
        """Open loop; returns only the features [N, frames, F]."""
        return self.rollout_reply(actions, bags, smoothing_window).arrays["features"]

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class TrainingServer(ServerConnection):
    """One Godot process running N characters. Use as a context manager, or call close()."""

    def __init__(self, slot_count: int = 1, *, decision_period: int = 5, slots_per_world: int = 16,
                 start_timeout_s: float = 60.0, reply_timeout_s: float = 120.0, idle_timeout_s: float | None = None):
        """`slots_per_world` = 1 puts every character in a physics world of its own: bitwise-identical results
        whatever the slot, at about 2.7 times the cost (docs/env.md, Episodes). `idle_timeout_s`: default
        `IDLE_TIMEOUT_S`."""
        self._process: subprocess.Popen[str] | None = None
        self._socket: socket.socket | None = None
        self.reply_timeout_s = reply_timeout_s
        self.idle_timeout_s = IDLE_TIMEOUT_S if idle_timeout_s is None else idle_timeout_s
        self.secret = secrets.token_hex(16)
        """the server's secret, fresh for each server: a connection must say it in its hello"""
        self._process = start_godot([
            # --fixed-fps: run frames back to back without waiting for the wall clock. The server checks the
            # physics rate itself and blocks between commands, so this value only sets steps per frame.
            "--headless", "--fixed-fps", "120", "--path", str(GODOT_PROJECT), SERVER_SCENE, "--",
            "--port=0", f"--slots={slot_count}", f"--decision-period={decision_period}",
            f"--slots-per-world={slots_per_world}", f"--idle-timeout-s={self.idle_timeout_s}",
        ], env={**os.environ, SECRET_VARIABLE: self.secret})
        assert self._process.stdout is not None
        # Read for the server's whole life: a pipe left unread fills, and the server blocks in its log.
        self.output = GodotOutput(self._process.stdout, READY_PREFIX)
        try:
            port = self.port = self._wait_until_ready(start_timeout_s)
            self.info = self._connect(port, start_timeout_s)
        except BaseException:
            self.close()
            raise
        self.last_request_s = time.monotonic()

    def _wait_until_ready(self, timeout_s: float) -> int:
        line = self.output.wait_for(timeout_s)
        if line is None:
            state = "exited before it was ready" if self.output.ended else f"was not ready within {timeout_s:.0f} s"
            raise GodotRunError(f"the training server {state}:\n{self.output.tail()}", self.output.text())
        fields = dict(item.split("=", 1) for item in line[len(READY_PREFIX):].split())
        return int(fields["port"])

    def _connect(self, port: int, timeout_s: float) -> ServerInfo:
        """Connects and says hello; while the server says it is busy (other processes hold its connections),
        tries again a few times (the server closes the oldest connection waiting for a hello)."""
        for attempt in range(CONNECT_ATTEMPTS):
            self._socket = socket.create_connection(("127.0.0.1", port), timeout=timeout_s)
            self._socket.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._socket.settimeout(self.reply_timeout_s)
            try:
                return self._handshake()
            except (ServerBusyError, ServerClosedError, ConnectionError) as error:
                self._socket.close()
                self._socket = None
                if attempt == CONNECT_ATTEMPTS - 1 or (self._process is not None and self._process.poll() is not None):
                    if isinstance(error, ServerBusyError):
                        raise
                    raise ServerClosedError(f"the training server closed our connection before its handshake ({error}):\n"
                                            f"{self.output.tail()}") from None
                time.sleep(0.05 * 2 ** attempt)
        raise AssertionError("unreachable")

    def _handshake(self) -> ServerInfo:
        try:
            reply = self.request(hello_message(self.secret))
        except ServerError as error:
            text = str(error)
            if "busy" in text:
                raise ServerBusyError(f"the training server on port {self.port} refused our connection: {text} (other "
                                      f"processes on this machine hold its connections; tried {CONNECT_ATTEMPTS} times)") from None
            if "protocol version" in text or "protocol_version" in text:
                raise ProtocolVersionError(f"the server refused our protocol version {PROTOCOL_VERSION}: {text} "
                                           "(rebuild the extension: ./dev setup)") from None
            raise ServerError(f"the training server refused our hello: {text}") from None
        if reply.fields.get("protocol_version") != PROTOCOL_VERSION:
            raise ProtocolVersionError(f"server speaks protocol {reply.fields.get('protocol_version')}, we speak {PROTOCOL_VERSION}")
        f = reply.fields
        return ServerInfo(f["slot_count"], f["decision_period"], f["physics_hz"], f["spec_hash"], f["spec_version"],
                          f["extension_version"], f["action_names"], f["action_lower_rad"], f["action_upper_rad"],
                          f["observation_names"], f["feature_names"], EpisodeConditions.from_wire(f["default_bag"]), f["reach_volume"],
                          MirrorRules.from_wire(f["mirror"]), f["stance_guard_actions"],
                          f["loaded_guard_actions"], float(f["stance_lead_forward_m"]))

    @property
    def pid(self) -> int | None:
        """The Godot process's id (None once closed)."""
        return self._process.pid if self._process is not None else None

    def send(self, message: Message) -> None:
        if self._socket is None:
            raise PunchError("the training server is closed")
        self.last_request_s = time.monotonic()
        write_frame(self._socket.sendall, *message.parts())

    def receive(self) -> Message:
        if self._socket is None:
            raise PunchError("the training server is closed")
        return receive(self._socket)

    def close(self) -> None:
        """Says goodbye, then ends the process (killed by its PID if it does not exit). Idempotent."""
        if self._socket is not None:
            try:
                self._socket.settimeout(2.0)
                self.send(close_message())
            except (OSError, PunchError):
                pass
            self._socket.close()
            self._socket = None
        if self._process is not None:
            process, self._process = self._process, None
            # The output is closed once its reader has seen it end (the process group is gone by then).
            stop_godot(process, close_output=False)
            if self.output.join(5.0) and process.stdout is not None:
                process.stdout.close()

    def __del__(self) -> None:
        self.close()


def exchange(servers: list[ServerConnection], messages: list[Message]) -> list[Message]:
    """Sends one message to each server, then reads every reply: the processes work in parallel."""
    for server, message in zip(servers, messages, strict=True):
        server.send(message)
    return [server.receive() for server in servers]


__all__ = ["ServerConnection", "ServerError", "ServerInfo", "TrainingServer", "ProtocolVersionError", "ServerBusyError", "exchange"]
