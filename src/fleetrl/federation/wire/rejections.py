"""Why a received message or status is rejected: :class:`Reason` and :class:`MessageRejected`, and the checks
of an envelope's small fields (metrics, names, settings, counts, a round's configuration) that raise them.

The lowest module of the wire format: :mod:`fleetrl.federation.wire.signing` raises these, and
:mod:`fleetrl.federation.wire.messages` (which sits above signing) raises and re-exports them.
"""

from __future__ import annotations

import math
from enum import StrEnum

MAX_METRICS = 32
"""Most metrics one message may carry."""
MAX_NAME = 64
"""Longest metric name or id accepted."""
MAX_TEXT = 1024
"""Longest setting value or detail text accepted."""
MAX_COUNT = 2**31 - 1
"""Largest ``samples`` or ``units`` accepted."""


class Reason(StrEnum):
    """Why a message was rejected (by the decoder, or by the chief or worker that received it)."""

    OVERSIZED = "oversized"
    NOT_MSGPACK = "not msgpack"
    MALFORMED = "malformed envelope"
    WRONG_VERSION = "wrong version"
    UNKNOWN_TYPE = "unknown type"
    WRONG_RUN_ID = "wrong run id"
    UNKNOWN_SENDER = "unknown sender"
    BAD_ROUND = "bad round"
    BAD_METRICS = "bad metrics"
    LAYOUT_MISMATCH = "tensor names/shapes do not match the layout"
    NOT_FINITE = "NaN or Inf"
    UNSIGNED = "unsigned"
    BAD_SIGNATURE = "bad signature"
    # Raised by the receivers, not the decoder:
    TOPIC_MISMATCH = "sender does not match topic"
    UNEXPECTED_TYPE = "type not expected from this sender"
    STALE_ROUND = "stale round"
    FUTURE_ROUND = "future round"
    DUPLICATE = "duplicate (sender, round)"
    NOT_IN_W = "sender no longer in W"
    RUN_OVER = "run is over"
    REFUSED = "sender was refused at join"
    REPLAYED = "replayed status"


class MessageRejected(Exception):
    """A received message failed validation; ``reason`` says which rule, ``detail`` says what was seen."""

    def __init__(self, reason: Reason, detail: str = "") -> None:
        """:param reason: the rule that failed.  :param detail: what was wrong, for the log."""
        super().__init__(f"{reason.value}: {detail}" if detail else reason.value)
        self.reason = reason
        self.detail = detail


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
