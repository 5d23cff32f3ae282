"""Device topics (``fleetrl/<run_id>/device/<unit>/cmd``, ``…/state``, ``…/status``) and their msgpack
messages, a command (link → bridge) and a state (bridge → link), fully validated on decoding
(docs/protocol.md, "Device bridges")."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import msgpack
import numpy as np

VERSION = 2  # of both messages
MAX_VECTOR = 64  # most float32 values of an observation or a command vector
MAX_ERROR = 200  # characters of a refusal reason kept on the wire
HEADER_BYTES = 64  # msgpack bytes of a message's map, keys, scalars and length prefixes (at most 60)
MAX_PAYLOAD = HEADER_BYTES + 4 * MAX_VECTOR + 4 * MAX_ERROR  # longer messages are refused undecoded
MAX_SEQ = 2**63 - 1
MAX_SID = 2**32 - 1  # one session id per link instance
MAX_SEED = 2**64 - 1  # one 64-bit word of numpy's SeedSequence entropy

FLAG_PROTECTIVE_STOP = 1  # the arm (cart) passed its limit; motor off until the next reset
FLAG_WATCHDOG = 2  # no command for the watchdog time; the motor was switched off

OPS = ("step", "reset")
_RUN_ID = re.compile(r"[A-Za-z0-9_.-]{1,64}")
_COMMAND_KEYS = {"step": {"v", "sid", "seq", "op", "a"}, "reset": {"v", "sid", "seq", "op", "seed"}}
_STATE_KEYS = {"v", "sid", "seq", "t", "obs", "flags"}


class WireError(ValueError):
    """A device message that fails validation; ``sid`` and ``seq`` set when its header was valid."""

    def __init__(self, reason: str, sid: int | None = None, seq: int | None = None) -> None:
        super().__init__(reason)
        self.sid = sid
        self.seq = seq


def device_topic(run_id: str, unit: int, leaf: str) -> str:
    """``fleetrl/<run_id>/device/<unit>/<leaf>`` with ``leaf`` one of ``cmd``, ``state``, ``status``."""
    if not isinstance(run_id, str) or not _RUN_ID.fullmatch(run_id):
        raise ValueError(f"bad run id {run_id!r}: use 1-64 characters from A-Z a-z 0-9 _ . -")
    if isinstance(unit, bool) or not isinstance(unit, int) or unit < 0:
        raise ValueError(f"bad unit {unit!r}: use a non-negative integer")
    if leaf not in ("cmd", "state", "status"):
        raise ValueError(f"bad device topic leaf {leaf!r} (choose cmd, state or status)")
    return f"fleetrl/{run_id}/device/{unit}/{leaf}"


ONLINE = b"online"  # retained status of a running bridge
OFFLINE = b"offline"  # of a bridge that stopped (its last will, or a clean goodbye)


@dataclass(frozen=True)
class Command:
    """One command to a bridge: ``step`` (with an ``action`` index or a ``command`` vector) or ``reset``
    (with its ``seed``), from link session ``sid``, to be answered with sequence number ``seq``."""

    sid: int
    seq: int
    op: str
    action: int | None = None
    command: tuple[float, ...] | None = None
    seed: int | None = None

    @classmethod
    def step(cls, sid: int, seq: int, action: object) -> Command:
        """A step carrying an action index (int) or a command vector (floats); ValueError otherwise."""
        if isinstance(action, int | np.integer) and not isinstance(action, bool | np.bool_):
            return cls(sid, seq, "step", action=int(action))
        vectors = np.ndarray | list | tuple | float | np.floating
        vector = np.asarray(action) if isinstance(action, vectors) else None
        if vector is None or not np.issubdtype(vector.dtype, np.floating) or vector.ndim > 1:
            raise ValueError(f"a step takes an action index (int) or a 1-D vector of floats, got {action!r}")
        return cls(sid, seq, "step", command=tuple(vector.reshape(-1).astype(np.float32).tolist()))


@dataclass(frozen=True)
class State:
    """One state from a bridge, answering the command with the same ``(sid, seq)``: the device's clock
    ``time``, the observation, ``FLAG_*`` bits, or why the command was refused (``obs`` then empty)."""

    sid: int
    seq: int
    time: float
    obs: np.ndarray
    flags: int = 0
    error: str | None = None


def encode_command(command: Command) -> bytes:
    """The msgpack bytes of ``command``."""
    body: dict[str, Any] = {"v": VERSION, "sid": command.sid, "seq": command.seq, "op": command.op}
    if command.op == "step":
        if command.command is not None:
            body["a"] = np.asarray(command.command, dtype="<f4").tobytes()
        else:
            body["a"] = command.action
    else:
        body["seed"] = command.seed
    return bytes(msgpack.packb(body))


def encode_state(state: State) -> bytes:
    """The msgpack bytes of ``state`` (the observation as little-endian float32 bytes)."""
    body: dict[str, Any] = {
        "v": VERSION,
        "sid": state.sid,
        "seq": state.seq,
        "t": state.time,
        "obs": np.asarray(state.obs, dtype="<f4").tobytes(),
        "flags": state.flags,
    }
    if state.error is not None:
        body["err"] = state.error[:MAX_ERROR]
    return bytes(msgpack.packb(body))


def decode_command(payload: bytes, n_actions: int, command_size: int) -> Command:
    """The command in ``payload`` for a unit with ``n_actions`` action indices and command vectors of
    ``command_size``; WireError otherwise."""
    body = _unpack(payload)
    sid, seq = _header(body)
    try:
        return _command(body, sid, seq, n_actions, command_size)
    except WireError as err:
        raise WireError(str(err), sid, seq) from None


def _command(body: dict[str, Any], sid: int, seq: int, n_actions: int, command_size: int) -> Command:
    op = body.get("op")
    if op not in OPS:
        raise WireError(f"unknown op {op!r} (choose step or reset)")
    _exact_keys(body, _COMMAND_KEYS[op])
    if op == "reset":
        seed = body["seed"]
        if seed is not None and not _int_in(seed, 0, MAX_SEED):
            raise WireError(f"seed {seed!r} is not None or an integer 0 to 2**64-1")
        return Command(sid, seq, "reset", seed=seed)
    action = body["a"]
    if isinstance(action, bytes):
        return Command(sid, seq, "step", command=_command_vector(action, command_size))
    vector = f"a command vector of {command_size} float32 values as bytes"
    if not isinstance(action, int) or isinstance(action, bool):
        raise WireError(f"action {action!r} is neither an action index (an integer) nor {vector}")
    if n_actions == 0:
        raise WireError(f"this unit takes no action index, got {action!r} (send {vector})")
    if not _int_in(action, 0, n_actions - 1):
        raise WireError(
            f"action {action!r} is out of range (choose an integer 0 to {n_actions - 1}, or send {vector})"
        )
    return Command(sid, seq, "step", action=action)


def _command_vector(data: bytes, size: int) -> tuple[float, ...]:
    if len(data) != 4 * size:
        raise WireError(
            f"command vector of {len(data)} bytes: this unit takes {size} little-endian float32 values "
            f"({4 * size} bytes)"
        )
    values = tuple(np.frombuffer(data, dtype="<f4").tolist())
    if not all(map(math.isfinite, values)):
        raise WireError("command vector holds a value that is not finite")
    return values


def decode_state(payload: bytes) -> State:
    """Validate and decode a state; WireError otherwise."""
    body = _unpack(payload)
    error = body.get("err")
    _exact_keys(body, _STATE_KEYS | ({"err"} if "err" in body else set()))
    sid, seq = _header(body)
    t, obs, flags = body["t"], body["obs"], body["flags"]
    if not isinstance(t, float | int) or isinstance(t, bool) or not math.isfinite(t):
        raise WireError(f"device time {t!r} is not a finite number")
    if not _int_in(flags, 0, 255):
        raise WireError(f"flags {flags!r} are not an integer 0 to 255")
    if not isinstance(obs, bytes) or len(obs) % 4 or len(obs) > 4 * MAX_VECTOR:
        raise WireError(f"obs must be at most {MAX_VECTOR} little-endian float32 values as bytes")
    values = np.frombuffer(obs, dtype="<f4").astype(np.float32)
    if not np.all(np.isfinite(values)):
        raise WireError("obs holds a value that is not finite")
    if error is not None and (not isinstance(error, str) or len(error) > MAX_ERROR):
        raise WireError("err must be a short string")
    if error is None and values.size == 0:
        raise WireError("a state without err must carry an observation")
    return State(sid, seq, float(t), values, flags, error)


def _unpack(payload: bytes) -> dict[str, Any]:
    if len(payload) > MAX_PAYLOAD:
        raise WireError(f"message of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    try:
        body = msgpack.unpackb(payload, raw=False, strict_map_key=True, use_list=True)
    except Exception as exc:  # msgpack raises several unrelated types on garbage
        raise WireError(f"not msgpack: {type(exc).__name__}: {exc}") from None
    if not isinstance(body, dict):
        raise WireError(f"expected a map, got {type(body).__name__}")
    version = body.get("v")
    if version != VERSION or isinstance(version, bool):
        raise WireError(f"unsupported version {version!r} (this side speaks {VERSION})")
    return body


def _exact_keys(body: dict[str, Any], expected: set[str]) -> None:
    keys = set(body)
    if keys != expected:
        missing, extra = sorted(expected - keys), sorted(map(str, keys - expected))
        raise WireError(f"fields wrong: missing {missing}, unexpected {extra}")


def _header(body: dict[str, Any]) -> tuple[int, int]:
    sid: Any = body.get("sid")
    seq: Any = body.get("seq")
    if not _int_in(sid, 0, MAX_SID):
        raise WireError(f"sid {sid!r} is not an integer 0 to 2**32-1")
    if not _int_in(seq, 0, MAX_SEQ):
        raise WireError(f"seq {seq!r} is not an integer 0 to 2**63-1")
    return sid, seq


def _int_in(value: object, low: int, high: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high
