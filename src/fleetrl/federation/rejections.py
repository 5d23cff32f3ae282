"""Why a received message or status is rejected: :class:`Reason` and :class:`MessageRejected`.

The lowest module of the wire format: :mod:`fleetrl.federation.signing` raises these, and
:mod:`fleetrl.federation.messages` (which sits above signing) raises and re-exports them.
"""

from __future__ import annotations

from enum import StrEnum


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
