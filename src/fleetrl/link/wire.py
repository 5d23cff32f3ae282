"""Device topics and the two small msgpack messages on them: a command (link → bridge) and a state
(bridge → link).

Topics, one set per unit under the run: ``fleetrl/<run_id>/device/<unit>/cmd``, ``…/state`` and ``…/status``
(retained ``online`` / ``offline``, the bridge's last will). Both messages are msgpack maps with short keys;
the decoders check every field (version, types, ranges, size) and raise :class:`WireError` with a reason, so
a bad message is rejected and logged, never acted on. No pickle.

Command: ``{"v": 1, "sid": session, "seq": n, "op": "step", "a": action}`` or
``{"v": 1, "sid": session, "seq": n, "op": "reset", "seed": seed | None}``.
State: ``{"v": 1, "sid": session, "seq": n, "t": device seconds, "obs": float32 LE bytes, "flags": bits}``
plus ``"err": reason`` when the bridge refused the command.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import msgpack
import numpy as np

VERSION = 1
"""wire version of both messages"""
MAX_PAYLOAD = 512
"""bytes; anything longer is refused before it is decoded"""
MAX_SEQ = 2**63 - 1
"""sequence numbers are non-negative 63-bit integers"""
MAX_SID = 2**32 - 1
"""session ids are unsigned 32-bit integers (one per link instance)"""
MAX_SEED = 2**64 - 1
"""a reset seed fits numpy's SeedSequence entropy of one 64-bit word"""
MAX_OBS = 16
"""most observation components a state may carry"""
MAX_ERROR = 200
"""characters of a refusal reason kept on the wire"""

FLAG_PROTECTIVE_STOP = 1
"""the arm (cart) went past its limit; the motor is off until the next reset"""
FLAG_WATCHDOG = 2
"""commands stopped arriving for the watchdog time; the motor was switched off"""

OPS = ("step", "reset")
_RUN_ID = re.compile(r"[A-Za-z0-9_.-]{1,64}")
_COMMAND_KEYS = {"step": {"v", "sid", "seq", "op", "a"}, "reset": {"v", "sid", "seq", "op", "seed"}}
_STATE_KEYS = {"v", "sid", "seq", "t", "obs", "flags"}


class WireError(ValueError):
    """A device message that fails validation; the text says what is wrong with it.

    ``sid`` and ``seq`` are set when the message's header was valid, so the refusal can be answered.
    """

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


ONLINE = b"online"
"""retained status of a running bridge"""
OFFLINE = b"offline"
"""status of a bridge that stopped (its last will, or a clean goodbye)"""


@dataclass(frozen=True)
class Command:
    """One command to a bridge.

    :param sid: the sending link's session id (a new link takes the unit over)
    :param seq: the sequence number the state answering it will carry
    :param op: ``step`` (apply action ``action`` for one control period) or ``reset`` (device-side reset)
    :param action: action index of a step
    :param seed: seed of a reset (None: unseeded)
    """

    sid: int
    seq: int
    op: str
    action: int = 0
    seed: int | None = None


@dataclass(frozen=True)
class State:
    """One state from a bridge, answering the command with the same ``(sid, seq)``.

    :param sid: session id of the command answered
    :param seq: sequence number of the command answered
    :param time: the device's clock (s) when the observation was read
    :param obs: the observation (float32)
    :param flags: ``FLAG_*`` bits
    :param error: why the command was refused (then ``obs`` is empty)
    """

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


def decode_command(payload: bytes, n_actions: int) -> Command:
    """Validate and decode a command for a device with ``n_actions`` actions; WireError otherwise."""
    body = _unpack(payload)
    sid, seq = _header(body)
    try:
        return _command(body, sid, seq, n_actions)
    except WireError as err:
        raise WireError(str(err), sid, seq) from None


def _command(body: dict[str, Any], sid: int, seq: int, n_actions: int) -> Command:
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
    if not _int_in(action, 0, n_actions - 1):
        raise WireError(f"action {action!r} is out of range (choose an integer 0 to {n_actions - 1})")
    return Command(sid, seq, "step", action=action)


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
    if not isinstance(obs, bytes) or len(obs) % 4 or len(obs) > 4 * MAX_OBS:
        raise WireError(f"obs must be at most {MAX_OBS} little-endian float32 values as bytes")
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
