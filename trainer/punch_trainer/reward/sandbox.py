"""A user's reward runs in its own worker process, where it cannot end, hang or corrupt the run.

`load_reward` (reward/rewards.py) gives a reward named by a file or module an `IsolatedFunction`: the user's
module is imported, and the function called, in a child Python process (`python -m
punch_trainer.reward.sandbox`). Each call sends a copy of the features (bytes over a pipe: nothing of the
run's memory, `.base` included, is reachable from the reward) and reads back plain float64 arrays, checked
here for names, shape and size, never unpickled. The trainer waits with a deadline and kills the worker
(SIGKILL, which no handler can catch) when it passes, so `os._exit` however bound, a bare `except:` retry
loop, SIGALRM ignored or overridden, or a crash end only the worker; the error says which it was. A worker
that died between calls is restarted. The worker has its own session (Ctrl-C goes to the trainer only) and
dies with the trainer (PR_SET_PDEATHSIG). This is isolation of mistakes, not a security boundary: the
reward is code the user chose to run, with the user's rights.

Wire format, both ways: the trainer's one framing (framing.py): a JSON header and the raw array data.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
import types
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from punch_trainer.errors import PunchError
from punch_trainer.framing import FrameError, FrameLimits, read_frame, write_frame

STARTUP_ALLOWANCE_S = 30.0
"""Time a new worker may take to start Python and numpy, on top of the reward's own limit for its import."""
_LIMITS = FrameLimits(max_header_bytes=1 << 20)
_MAX_TERMS = 256
_MAX_MESSAGE_CHARS = 2000
_FEATURE_DTYPES = {"<f4": np.float32, "<f8": np.float64}


class RewardError(PunchError):
    """A reward could not be loaded, raised, or returned something that is not a per-frame reward."""


Terms = dict[str, np.ndarray]


class Frames:
    """Named access to features [..., frames, F]: `f["fist_r_vel_z"]` is [..., frames]."""

    def __init__(self, features: np.ndarray, feature_names: list[str]):
        self.features = features
        self._index = {name: i for i, name in enumerate(feature_names)}

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.features[..., self._index[name]]
        except KeyError:
            raise KeyError(f"no feature '{name}'; features are: {', '.join(self._index)}") from None

    @property
    def names(self) -> list[str]:
        return list(self._index)


_KIND_WORDS = {"c": "complex numbers", "U": "strings", "S": "bytes", "O": "Python objects", "M": "dates",
               "m": "time spans", "V": "raw records"}


def result_terms(reward_name: str, result: object, expected: tuple[int, ...]) -> Terms:
    """A reward's result as float64 terms of shape `expected`: refuses anything but real numbers (bool counts
    as 0/1), the wrong shape, NaN or infinity, with an error naming the reward and the term."""
    if isinstance(result, dict):
        terms = result
    elif isinstance(result, (np.ndarray, float, int, np.floating, np.integer)):
        terms = {"reward": result}
    else:
        raise RewardError(f"reward '{reward_name}' returned {type(result).__name__}; it must return an array of "
                          "per-frame rewards or a dict of such arrays")
    if not terms:
        raise RewardError(f"reward '{reward_name}' returned an empty dict; it must name at least one term")
    if len(terms) > _MAX_TERMS:
        raise RewardError(f"reward '{reward_name}' returned {len(terms)} terms; at most {_MAX_TERMS}")
    out = {}
    for name, values in terms.items():
        if not isinstance(name, str):
            raise RewardError(f"reward '{reward_name}' named a term {name!r}; term names must be strings")
        try:
            array = np.asarray(values)
        except Exception as error:  # a user's object may fail its conversion in any way
            raise RewardError(f"reward '{reward_name}' term '{name}' is not an array of numbers: {type(error).__name__}: {error}") from None
        if array.dtype.kind not in "biuf":
            what = _KIND_WORDS.get(array.dtype.kind, str(array.dtype))
            raise RewardError(f"reward '{reward_name}' term '{name}' returned {what} ({array.dtype}); a reward must be "
                              "real numbers")
        if array.shape != expected:
            raise RewardError(f"reward '{reward_name}' term '{name}' has shape {array.shape}; expected {expected} (one value per frame)")
        array = array.astype(np.float64)
        if not np.all(np.isfinite(array)):
            raise RewardError(f"reward '{reward_name}' term '{name}' returned NaN or infinity")
        out[name] = array
    return out


class _DeadlineError(Exception):
    pass


class _ClosedError(Exception):
    pass


def _write_all(fd: int, data: bytes | memoryview, deadline: float) -> None:
    view = memoryview(data).cast("B")
    while view:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise _DeadlineError
        _, ready, _ = select.select([], [fd], [], remaining)
        if not ready:
            continue
        try:
            written = os.write(fd, view[:1 << 20])
        except BlockingIOError:
            continue
        except (BrokenPipeError, OSError):
            raise _ClosedError from None
        view = view[written:]


def _read_exact(fd: int, size: int, deadline: float | None) -> bytes:
    chunks, got = [], 0
    while got < size:
        if deadline is not None:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise _DeadlineError
            ready, _, _ = select.select([fd], [], [], remaining)
            if not ready:
                continue
        try:
            chunk = os.read(fd, min(size - got, 1 << 20))
        except BlockingIOError:
            continue
        if not chunk:
            raise _ClosedError
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def _send(fd: int, header: dict[str, Any], payload: bytes | memoryview, deadline: float) -> None:
    write_frame(lambda data: _write_all(fd, data, deadline), json.dumps(header).encode(), payload)


def _receive(fd: int, deadline: float | None) -> tuple[dict[str, Any], bytes]:
    """A header and its payload; FrameError for anything malformed (the other end may be the user's code)."""
    header_bytes, payload = read_frame(lambda count: _read_exact(fd, count, deadline), _LIMITS)
    try:
        header = json.loads(header_bytes)
    except ValueError as error:
        raise FrameError(f"a header that is not JSON ({error})") from None
    if not isinstance(header, dict):
        raise FrameError("a header that is not a JSON object")
    return header, payload


def _stop(process: subprocess.Popen[bytes], fds: list[int]) -> None:
    # The worker leads its own process group: processes the reward started (and that may hold its pipes) go too.
    with contextlib.suppress(OSError):
        os.killpg(process.pid, signal.SIGKILL)
    if process.poll() is None:
        process.kill()
        process.wait()
    for fd in fds:
        with contextlib.suppress(OSError):
            os.close(fd)
    fds.clear()


class IsolatedFunction:
    """A reward function that lives in a worker process: calling it with `Frames` returns float64 terms.
    `spec` is what the user named (for messages); `location` a file path (absolute) or module name."""

    def __init__(self, spec: str, location: str, function_name: str, time_limit_s: Callable[[], float]):
        self.spec, self.location, self.function_name, self.time_limit_s = spec, location, function_name, time_limit_s
        self.source_sha256 = ""
        self._lock = threading.Lock()
        self._process: subprocess.Popen[bytes] | None = None
        self._fds: list[int] = []
        self._finalizer: weakref.finalize | None = None  # type: ignore[type-arg]

    def __getstate__(self) -> dict[str, Any]:
        return {"spec": self.spec, "location": self.location, "function_name": self.function_name,
                "time_limit_s": self.time_limit_s, "source_sha256": self.source_sha256}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["spec"], state["location"], state["function_name"], state["time_limit_s"])  # type: ignore[misc]
        self.source_sha256 = state["source_sha256"]

    def load(self) -> None:
        """Starts the worker and imports the reward there; RewardError if that fails."""
        with self._lock:
            self._ensure_started()

    def close(self) -> None:
        with self._lock:
            if self._finalizer is not None:
                self._finalizer()
            self._process = None

    def __call__(self, frames: Frames) -> Terms:
        features = np.asarray(frames.features)
        dtype = features.dtype.newbyteorder("<").str if features.dtype.kind == "f" else ""
        if dtype not in _FEATURE_DTYPES:
            features, dtype = features.astype(np.float64), "<f8"
        payload = np.ascontiguousarray(features, dtype=_FEATURE_DTYPES[dtype])
        expected = features.shape[:-1]
        with self._lock:
            self._ensure_started()
            header = self._exchange({"op": "call", "shape": list(features.shape), "dtype": dtype, "names": frames.names},
                                    payload.data, self.time_limit_s())
            return self._terms(header[0], header[1], expected)

    def _ensure_started(self) -> None:
        if self._process is not None and self._process.poll() is None:
            return
        if self._finalizer is not None:  # it died between calls (not during one): start another
            self._finalizer()
        request_read, request_write = os.pipe()
        reply_read, reply_write = os.pipe()
        package_root = str(Path(__file__).resolve().parents[2])
        environment = {k: v for k, v in os.environ.items() if "SECRET" not in k}
        environment["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, environment.get("PYTHONPATH")]))
        try:
            process = subprocess.Popen([sys.executable, "-m", "punch_trainer.reward.sandbox", str(request_read), str(reply_write)],
                                       pass_fds=(request_read, reply_write), stdin=subprocess.DEVNULL, env=environment,
                                       start_new_session=True)
        finally:
            os.close(request_read)
            os.close(reply_write)
        os.set_blocking(request_write, False)
        self._process, self._fds = process, [request_write, reply_read]
        self._finalizer = weakref.finalize(self, _stop, process, self._fds)
        header, _ = self._exchange({"op": "load", "location": self.location, "function": self.function_name}, b"",
                                   self.time_limit_s() + STARTUP_ALLOWANCE_S, importing=True)
        sha = header.get("sha256")
        self.source_sha256 = sha if isinstance(sha, str) else ""

    def _exchange(self, header: dict[str, Any], payload: bytes | memoryview, limit_s: float,
                  importing: bool = False) -> tuple[dict[str, Any], bytes]:
        assert self._process is not None
        request_write, reply_read = self._fds
        deadline = time.monotonic() + limit_s
        doing = "importing it" if importing else "on one batch"
        try:
            _send(request_write, header, payload, deadline)
            reply, data = _receive(reply_read, deadline)
        except _DeadlineError:
            ended = self._process.poll() is not None  # the reward ended its worker; a process it started kept the pipes
            self._kill()
            if ended:
                raise RewardError(self._death_message()) from None
            raise RewardError(f"reward '{self.spec}' took longer than {limit_s:g} s {doing} and was stopped "
                              "(set PUNCH_REWARD_TIME_LIMIT_S to allow more)") from None
        except _ClosedError:
            raise RewardError(self._death_message()) from None
        except FrameError as error:
            self._kill()
            raise RewardError(f"reward '{self.spec}' garbled its worker's reply ({error}); a reward must only return "
                              "its values") from None
        if reply.get("ok") is not True:
            if reply.get("fatal") or importing:
                self._kill()
            message = reply.get("error")
            message = message[:_MAX_MESSAGE_CHARS] if isinstance(message, str) else "failed"
            raise RewardError(f"reward '{self.spec}'{':' if importing else ''} {message}")
        return reply, data

    def _terms(self, reply: dict[str, Any], data: bytes, expected: tuple[int, ...]) -> Terms:
        names = reply.get("terms")
        size = int(np.prod(expected, dtype=np.int64))
        if (not isinstance(names, list) or not 0 < len(names) <= _MAX_TERMS or not all(isinstance(n, str) for n in names)
                or len(set(names)) != len(names) or len(data) != 8 * size * len(names)):
            self._kill()
            raise RewardError(f"reward '{self.spec}' garbled its worker's reply; a reward must only return its values")
        values = np.frombuffer(data, dtype="<f8").reshape(len(names), *expected)
        if not np.all(np.isfinite(values)):
            raise RewardError(f"reward '{self.spec}' returned NaN or infinity")
        return {name: values[i].astype(np.float64) for i, name in enumerate(names)}

    def _kill(self) -> None:
        if self._finalizer is not None:
            self._finalizer()

    def _death_message(self) -> str:
        assert self._process is not None
        try:
            code = self._process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self._kill()
            return f"reward '{self.spec}' closed its worker's pipes; a reward must only return its values"
        self._kill()
        if code >= 0:
            return (f"reward '{self.spec}' tried to exit the process (exit code {code}): it ended its worker process "
                    "(os._exit or similar); a reward must return its values")
        return f"reward '{self.spec}' ended its worker process with signal {signal.Signals(-code).name}"


def _file_module(path: Path) -> tuple[types.ModuleType, str]:
    source = path.read_bytes()
    module = types.ModuleType(f"punch_user_reward_{path.stem}")
    module.__file__ = str(path)
    sys.modules[module.__name__] = module
    exec(compile(source, str(path), "exec"), module.__dict__)  # the exact bytes hashed below
    return module, hashlib.sha256(source).hexdigest()


def _import(location: str) -> tuple[types.ModuleType, str]:
    if location.endswith(".py"):
        return _file_module(Path(location))
    module = importlib.import_module(location)
    file = getattr(module, "__file__", None)
    sha = hashlib.sha256(Path(file).read_bytes()).hexdigest() if isinstance(file, str) and Path(file).is_file() else ""
    return module, sha


def _handle(request: dict[str, Any], data: bytes, state: dict[str, Any]) -> tuple[dict[str, Any], bytes]:
    if request.get("op") == "load":
        location, function_name = str(request["location"]), str(request["function"])
        try:
            module, sha = _import(location)
        except SystemExit as error:
            return {"ok": False, "error": f"importing {location} tried to exit the process (exit code {error.code})"}, b""
        except BaseException as error:  # the user's module may fail in any way; say so, with its message
            return {"ok": False, "error": f"importing {location} failed: {type(error).__name__}: {error}"}, b""
        function = getattr(module, function_name, None)
        if not callable(function):
            return {"ok": False, "error": f"{location} has no function '{function_name}'"}, b""
        state["function"] = function
        return {"ok": True, "sha256": sha}, b""
    shape = tuple(int(n) for n in request["shape"])
    features = np.frombuffer(data, dtype=_FEATURE_DTYPES[request["dtype"]]).reshape(shape)  # read-only
    try:
        result = state["function"](Frames(features, [str(n) for n in request["names"]]))
        terms = result_terms("", result, shape[:-1])
    except RewardError as error:  # its text starts "reward '': ..."; the trainer names the reward
        return {"ok": False, "error": str(error).removeprefix("reward '' ")}, b""
    except SystemExit as error:
        return {"ok": False, "fatal": True, "error": f"tried to exit the process (exit code {error.code}); a reward must return its values"}, b""
    except BaseException as error:  # the user's code may fail in any way; say which reward and why
        return {"ok": False, "error": f"raised {type(error).__name__}: {error}"}, b""
    return {"ok": True, "terms": list(terms)}, b"".join(np.ascontiguousarray(v, dtype="<f8").tobytes() for v in terms.values())


def _serve(request_fd: int, reply_fd: int) -> None:
    try:  # die with the trainer, even while the reward loops
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    state: dict[str, Any] = {}
    while True:
        try:
            request, data = _receive(request_fd, None)
        except _ClosedError:
            return
        reply, payload = _handle(request, data, state)
        _send(reply_fd, reply, payload, time.monotonic() + 3600.0)


if __name__ == "__main__":
    _serve(int(sys.argv[1]), int(sys.argv[2]))
