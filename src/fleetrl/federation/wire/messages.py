"""Wire format of federation messages: a versioned msgpack envelope with raw little-endian float32 tensors
(an edge aggregator's sums: float64); never pickle. docs/protocol.md, "Envelope", lists its keys.
:func:`decode` validates all of it and raises only :class:`MessageRejected`, whatever the bytes.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Container, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import msgpack
import numpy as np

from fleetrl.federation.wire.signing import OVERHEAD as SIGNATURE_OVERHEAD
from fleetrl.federation.wire.signing import FleetKey, MessageRejected, Reason

VERSION = 8
"""Envelope version; a receiver rejects any other."""

Layout = Sequence[tuple[str, tuple[int, ...]]]
"""Names and shapes of the tensors of a message, in order (the actor's ``actor_layout()``)."""
RoundConfig = Mapping[str, float | str]
"""What the chief asks of every worker for a round (a scheme's ``configure``): name → number or short text."""

MESSAGE_TYPES: Mapping[str, bool] = {
    "parameters": True,  # worker → chief: "my criterion holds", with the parameters its scheme shares
    "average": True,  # chief → workers: the aggregated gradient (Algorithm 1, line 13) or model (fedavg)
    "transfer": True,  # chief → workers: a mature worker's parameters (Algorithm 1, line 8)
    "done": False,  # chief → workers: the run is over (W empty, or M rounds); the fleet's model if kept
    "welcome": False,  # chief → workers: round i is open; the last transferred θ* if there was a transfer
    "join": False,  # worker → chief: its shared settings, checked against the chief's before it plays
    "refused": False,  # chief → workers: the join of the worker in ``finished`` is refused (``detail``: why)
}
"""The protocol's message types → whether it must carry the layout's tensors. A scheme's own round message
(:func:`check_scheme_type`) always carries tensors; a receiver names those it takes (``scheme_types``)."""
SCHEME_TYPE = re.compile(r"[a-z][a-z0-9_]{0,31}")
OPTIONAL_TENSORS = frozenset({"welcome", "done"})  # types that carry no tensors or the whole layout

HEADER_ALLOWANCE = 64 * 1024  # bytes allowed beyond the tensors' own size by default_max_bytes
MAX_METRICS = 32  # most metrics (or settings, or config entries) one message may carry
MAX_NAME = 64  # longest metric name or id accepted
MAX_TEXT = 1024  # longest setting value or detail text accepted
MAX_COUNT = 2**31 - 1  # largest round, step or count accepted


def short(value: object) -> str:
    """A bounded, recursion-free description of a decoded value for a rejection detail."""
    if isinstance(value, str | bytes | int | float | bool) or value is None:
        return repr(value)[:MAX_NAME]
    return f"<{type(value).__name__}>"


def check_names(value: object, what: str) -> tuple[str, ...]:
    """``value`` as a tuple of worker ids (``what``: the field), or MALFORMED."""
    if not isinstance(value, list) or len(value) > 4096 or not all(isinstance(v, str) for v in value):
        raise MessageRejected(Reason.MALFORMED, f"{what} is not a list of strings")
    return tuple(value)


def check_count(value: object, what: str) -> int:
    """``value`` as a count in [0, MAX_COUNT] (``what``: the field), or MALFORMED."""
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= MAX_COUNT:
        raise MessageRejected(Reason.MALFORMED, f"{what} {short(value)}")
    return value


def check_config(value: object, error: type[ValueError] | None) -> dict[str, float | str]:
    """The ``config`` map checked: on decode a defect is a MALFORMED rejection, on encode ``error``."""
    why = None
    if not isinstance(value, dict) or len(value) > MAX_METRICS:
        why = f"config is not a map of at most {MAX_METRICS} entries"
    else:
        for key, val in value.items():
            number = isinstance(val, int | float) and not isinstance(val, bool) and math.isfinite(val)
            text = isinstance(val, str) and len(val) <= MAX_TEXT
            if not (isinstance(key, str) and len(key) <= MAX_NAME and (number or text)):
                why = f"config entry {short(key)}: not a finite number or a short text"
                break
    if why is not None:
        if error is not None:
            raise error(f"refusing to send: {why}")
        raise MessageRejected(Reason.MALFORMED, why)
    assert isinstance(value, dict)
    return {k: v if isinstance(v, str) else float(v) for k, v in value.items()}


def check_settings(value: object) -> dict[str, str]:
    """``value`` as a small map of setting name → short text, or MALFORMED."""
    if not isinstance(value, dict) or len(value) > MAX_METRICS:
        raise MessageRejected(Reason.MALFORMED, f"settings is not a map of at most {MAX_METRICS} entries")
    for key, val in value.items():
        if not (
            isinstance(key, str) and len(key) <= MAX_NAME and isinstance(val, str) and len(val) <= MAX_TEXT
        ):
            raise MessageRejected(Reason.MALFORMED, f"setting {short(key)}")
    return dict(value)


def check_metrics(value: object) -> dict[str, float]:
    """``value`` as a small map of metric name → finite number, or BAD_METRICS."""
    if not isinstance(value, dict) or len(value) > MAX_METRICS:
        raise MessageRejected(Reason.BAD_METRICS, f"not a map of at most {MAX_METRICS} entries")
    out: dict[str, float] = {}
    for key, val in value.items():
        if not isinstance(key, str) or len(key) > MAX_NAME:
            raise MessageRejected(Reason.BAD_METRICS, f"bad name {short(key)}")
        if not isinstance(val, int | float) or isinstance(val, bool) or not math.isfinite(val):
            raise MessageRejected(Reason.BAD_METRICS, f"{key}={short(val)}")
        out[key] = float(val)
    return out


def check_scheme_type(name: object, what: str = "a scheme") -> str:
    """``name`` if it can be a scheme's round-message type (:data:`SCHEME_TYPE`, not a protocol type)."""
    if not isinstance(name, str) or not SCHEME_TYPE.fullmatch(name) or name in MESSAGE_TYPES:
        raise ValueError(
            f"{what}: round_message {name!r} must be lower-case letters, digits and _ (at most 32, a letter "
            f"first) and not one of the protocol's types ({', '.join(MESSAGE_TYPES)})"
        )
    return name


@dataclass(frozen=True)
class Message:
    """One federation message, decoded (or to be encoded).

    :param type: one of :data:`MESSAGE_TYPES`, or a scheme's round message.
    :param sender: ``chief`` or a worker id.
    :param round: the round (episode) number, from 1.
    :param flat: the tensors as one flat float32 vector in layout order, or None for types without tensors.
    :param origin: for ``transfer``: the worker whose parameters are carried.
    :param finished: workers that leave W with this message (``transfer``).
    :param contributors: workers whose gradients were combined (``average``).
    :param step: the optimisation step within the round (schemes that send per step); 0 otherwise.
    :param settings: the settings all roles must share (``join``, ``welcome``).
    :param samples: the transitions the contribution stands for (0: not counted); ``units``: its units.
    :param config: what the chief asks of every worker for the round this message opens.
    :param staleness: rounds the fleet moved on while the worker played what it contributes.
    :param model_version: an asynchronous scheme's fleet model version (started from, or carried).
    :param epoch: the chief's epoch (:mod:`.chief.lease`): a chief's own, a worker's the highest it has seen.
    :param summed: ``flat`` is an edge aggregator's weighted sum, float64, standing for ``units``.
    """

    type: str
    run_id: str
    sender: str
    round: int
    flat: np.ndarray | None = None
    metrics: Mapping[str, float] = field(default_factory=dict)
    origin: str | None = None
    finished: tuple[str, ...] = ()
    contributors: tuple[str, ...] = ()
    step: int = 0
    settings: Mapping[str, str] = field(default_factory=dict)
    detail: str = ""
    samples: int = 0
    units: int = 1
    config: RoundConfig = field(default_factory=dict)
    staleness: int = 0
    model_version: int = 0
    epoch: int = 0
    version: int = VERSION
    summed: bool = False

    def tensors(self, layout: Layout) -> dict[str, np.ndarray]:
        """The flat vector split into named, shaped views following ``layout``."""
        if self.flat is None:
            return {}
        out: dict[str, np.ndarray] = {}
        start = 0
        for name, shape in layout:
            size = math.prod(shape)
            out[name] = self.flat[start : start + size].reshape(shape)
            start += size
        return out


def layout_size(layout: Layout) -> int:
    """Number of float32 elements described by ``layout``."""
    return sum(math.prod(shape) for _, shape in layout)


def default_max_bytes(layout: Layout) -> int:
    """Size cap for messages of ``layout``: the tensors' bytes plus :data:`HEADER_ALLOWANCE`."""
    return 4 * layout_size(layout) + HEADER_ALLOWANCE


def envelope(message: Message, *, layout: Layout) -> dict[str, Any]:
    """The msgpack map :func:`encode` packs (exposed so tests can build malformed variants)."""
    if message.type not in MESSAGE_TYPES and not SCHEME_TYPE.fullmatch(message.type):
        raise ValueError(f"unknown message type {message.type!r} (choose {', '.join(MESSAGE_TYPES)})")
    if MESSAGE_TYPES.get(message.type, True) or (
        message.type in OPTIONAL_TENSORS and message.flat is not None
    ):
        if message.flat is None:
            raise ValueError(f"a {message.type!r} message needs tensors")
        flat = np.ascontiguousarray(message.flat, dtype="<f8" if message.summed else "<f4").reshape(-1)
        if flat.size != layout_size(layout):
            raise ValueError(f"{flat.size} values do not fit the layout ({layout_size(layout)})")
        tensors = [[name, list(shape)] for name, shape in layout]
        data = flat.tobytes()
    else:
        tensors, data = [], b""
    return {
        "version": message.version,
        "type": message.type,
        "run_id": message.run_id,
        "sender": message.sender,
        "round": message.round,
        "metrics": {str(k): float(v) for k, v in message.metrics.items()},
        "origin": message.origin,
        "finished": list(message.finished),
        "contributors": list(message.contributors),
        "step": message.step,
        "settings": {str(k): str(v) for k, v in message.settings.items()},
        "detail": message.detail,
        "samples": message.samples,
        "units": message.units,
        "config": {str(k): v if isinstance(v, str) else float(v) for k, v in message.config.items()},
        "staleness": message.staleness,
        "model_version": message.model_version,
        "epoch": message.epoch,
        "tensors": tensors,
        "data": data,
    }


_KEYS = frozenset(envelope(Message("done", "", "", 0), layout=()))
"""the keys of every envelope"""


def encode(message: Message, *, layout: Layout, key: FleetKey | None = None) -> bytes:
    """Serialise ``message`` (tensors following ``layout``), signed with ``key`` if given; ValueError for
    what every receiver would reject (unknown type, tensors missing or not fitting, non-finite values)."""
    env = envelope(message, layout=layout)
    if (
        env["data"]
        and not np.isfinite(np.frombuffer(env["data"], dtype="<f8" if message.summed else "<f4")).all()
    ):
        raise ValueError(f"refusing to send a {message.type!r} message with NaN or Inf values")
    if not all(math.isfinite(v) for v in env["metrics"].values()):
        raise ValueError("refusing to send non-finite metrics")
    check_config(env["config"], error=ValueError)
    packed = bytes(msgpack.packb(env, use_bin_type=True))
    return packed if key is None else key.sign(packed)


def decode(
    payload: bytes,
    *,
    run_id: str,
    known_senders: Container[str],
    layout: Layout,
    max_bytes: int | None = None,
    key: FleetKey | None = None,
    scheme_types: Collection[str] = (),
    layouts: Mapping[str, Layout] | None = None,
    sums: bool = False,
) -> Message:
    """Parse and validate one message of ``run_id`` from one of ``known_senders``; raise
    :class:`MessageRejected` (only) if anything is wrong.

    :param layout: tensor names and shapes every tensor-carrying message must match exactly.
    :param max_bytes: size cap; default :func:`default_max_bytes` of ``layout`` (plus the signature's).
    :param key: the fleet key: the payload must be signed with it (checked before anything is parsed).
    :param scheme_types: the scheme's round-message types the receiver takes besides :data:`MESSAGE_TYPES`.
    :param layouts: message type → its own layout, where it is not ``layout``.
    :param sums: a scheme's round message may carry an edge aggregator's float64 sum.
    """
    layouts = layouts or {}
    cap = max(map(default_max_bytes, [layout, *layouts.values()])) if max_bytes is None else max_bytes
    if sums and max_bytes is None:
        cap += 4 * layout_size(layout)
    if key is not None:
        cap += SIGNATURE_OVERHEAD
    if not isinstance(payload, bytes | bytearray | memoryview):
        raise MessageRejected(Reason.NOT_MSGPACK, f"payload is {type(payload).__name__}, not bytes")
    if len(payload) > cap:
        raise MessageRejected(Reason.OVERSIZED, f"{len(payload)} bytes > cap {cap}")
    if key is not None:
        payload = key.open(bytes(payload))
    try:
        env = msgpack.unpackb(bytes(payload), raw=False, use_list=True, strict_map_key=True, max_bin_len=cap)
    except Exception as exc:  # msgpack raises many types (ExtraData, FormatError, ValueError, Unicode...)
        raise MessageRejected(Reason.NOT_MSGPACK, type(exc).__name__) from None
    if not isinstance(env, dict):
        raise MessageRejected(Reason.MALFORMED, f"top level is {type(env).__name__}, not a map")
    if env.get("version") != VERSION or isinstance(env.get("version"), bool):
        raise MessageRejected(Reason.WRONG_VERSION, f"{short(env.get('version'))} (expected {VERSION})")
    if set(env) != _KEYS:
        raise MessageRejected(
            Reason.MALFORMED, f"keys {sorted(map(str, env))[:20]} (expected {sorted(_KEYS)})"
        )
    mtype = env["type"]
    if not isinstance(mtype, str) or (mtype not in MESSAGE_TYPES and mtype not in scheme_types):
        raise MessageRejected(Reason.UNKNOWN_TYPE, short(mtype))
    if env["run_id"] != run_id:
        raise MessageRejected(Reason.WRONG_RUN_ID, short(env["run_id"]))
    sender = env["sender"]
    if not isinstance(sender, str) or sender not in known_senders:
        raise MessageRejected(Reason.UNKNOWN_SENDER, short(sender))
    rnd = env["round"]
    lowest = 0 if mtype == "join" else 1  # a join names the round its worker resumes at, 0 for none
    if not isinstance(rnd, int) or isinstance(rnd, bool) or not lowest <= rnd <= MAX_COUNT:
        raise MessageRejected(Reason.BAD_ROUND, short(rnd))
    metrics = check_metrics(env["metrics"])
    origin = env["origin"]
    if origin is not None and not isinstance(origin, str):
        raise MessageRejected(Reason.MALFORMED, "origin is not a string")
    step = check_count(env["step"], "step")
    detail = env["detail"]
    if not isinstance(detail, str) or len(detail) > MAX_TEXT:
        raise MessageRejected(Reason.MALFORMED, "detail is not a short string")
    samples, units = check_count(env["samples"], "samples"), check_count(env["units"], "units")
    config = check_config(env["config"], error=None)
    carries = MESSAGE_TYPES.get(mtype, True) or (mtype in OPTIONAL_TENSORS and env["tensors"] != [])
    wide = sums and (mtype in scheme_types or mtype == "parameters") and isinstance(env["data"], bytes)
    wide = wide and len(env["data"]) == 8 * layout_size(layout) > 0
    flat = _tensors(env["tensors"], env["data"], layouts.get(mtype, layout) if carries else (), wide)
    return Message(
        type=mtype,
        run_id=run_id,
        sender=sender,
        round=rnd,
        flat=flat if carries else None,
        metrics=metrics,
        origin=origin,
        finished=check_names(env["finished"], "finished"),
        contributors=check_names(env["contributors"], "contributors"),
        step=step,
        settings=check_settings(env["settings"]),
        detail=detail,
        samples=samples,
        units=units,
        config=config,
        staleness=check_count(env["staleness"], "staleness"),
        summed=wide,
        model_version=check_count(env["model_version"], "model_version"),
        epoch=check_count(env["epoch"], "epoch"),
    )


def _tensors(tensors: object, data: object, layout: Layout, wide: bool = False) -> np.ndarray:
    expected = [[name, list(shape)] for name, shape in layout]
    if tensors != expected:
        raise MessageRejected(
            Reason.LAYOUT_MISMATCH,
            f"got {short(tensors)} of {len(tensors) if isinstance(tensors, list) else '?'} entries",
        )
    width = 8 if wide else 4
    if not isinstance(data, bytes) or len(data) != width * layout_size(layout):
        size = len(data) if isinstance(data, bytes) else type(data).__name__
        raise MessageRejected(
            Reason.LAYOUT_MISMATCH, f"data has {size} bytes, layout needs {4 * layout_size(layout)}"
        )
    flat = np.frombuffer(data, "<f8" if wide else "<f4").astype(np.float64 if wide else np.float32)
    if not np.isfinite(flat).all():
        raise MessageRejected(Reason.NOT_FINITE, f"{int((~np.isfinite(flat)).sum())} non-finite values")
    return flat
