"""HMAC-SHA256 signatures of federation messages and node statuses under a fleet key, and why a message or
status is rejected (:class:`Reason`, :class:`MessageRejected`: the lowest module of the wire).

A signed message is ``MAGIC`` (``FRS1``) + HMAC-SHA256(key, ``MAGIC`` + envelope) + the msgpack envelope; the
envelope names the run, sender, type and round, so the signature binds all four. A status payload is
``<state> <incarnation>[ <name>=<value> …]``, signed: followed by ``<hex HMAC>`` over
``run_id/node/state/incarnation`` (and ``/<name>=<value> …`` when there are any). The incarnation grows with
every restart, so a replayed ``online`` or a late will of an earlier one is recognised.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path


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
        super().__init__(f"{reason.value}: {detail}" if detail else reason.value)
        self.reason = reason
        self.detail = detail


MAGIC = b"FRS1"  # the first bytes of a signed message
OVERHEAD = len(MAGIC) + 32  # bytes a signature adds to a message: MAGIC and an HMAC-SHA256 tag
MIN_KEY_BYTES = 16  # the shortest fleet key accepted


class FleetKey:
    """The secret every role of a fleet shares (at least :data:`MIN_KEY_BYTES` bytes); signs and verifies
    messages and statuses."""

    def __init__(self, secret: bytes) -> None:
        if len(secret) < MIN_KEY_BYTES:
            raise ValueError(f"a fleet key needs at least {MIN_KEY_BYTES} bytes, got {len(secret)}")
        self._secret = bytes(secret)

    @classmethod
    def from_file(cls, path: str | Path) -> FleetKey:
        """Read a key file (its bytes, surrounding whitespace removed)."""
        return cls(Path(path).read_bytes().strip())

    @classmethod
    def generate(cls) -> FleetKey:
        """A new random key (32 bytes, hex-encoded so the file is printable)."""
        return cls(os.urandom(32).hex().encode("ascii"))

    @property
    def secret(self) -> bytes:
        """The key's bytes (to write a key file)."""
        return self._secret

    def _tag(self, data: bytes) -> bytes:
        return hmac.new(self._secret, data, hashlib.sha256).digest()

    def sign(self, envelope: bytes) -> bytes:
        """``envelope`` framed with its signature."""
        return MAGIC + self._tag(MAGIC + envelope) + envelope

    def open(self, frame: bytes) -> bytes:
        """The envelope of a signed ``frame``; :class:`MessageRejected` ``unsigned`` or ``bad signature``."""
        if len(frame) < OVERHEAD or frame[: len(MAGIC)] != MAGIC:
            raise MessageRejected(Reason.UNSIGNED, f"{len(frame)} bytes without the {MAGIC!r} frame")
        tag, body = frame[len(MAGIC) : OVERHEAD], frame[OVERHEAD:]
        if not hmac.compare_digest(tag, self._tag(MAGIC + body)):
            raise MessageRejected(Reason.BAD_SIGNATURE, "HMAC does not match the fleet key")
        return bytes(body)

    def status_tag(self, run_id: str, node: str, state: str, incarnation: int, fields: str = "") -> str:
        """Hex HMAC of one status (``fields``: its ``name=value`` part, space-separated; none: empty)."""
        signed = f"{run_id}/{node}/{state}/{incarnation}" + (f"/{fields}" if fields else "")
        return self._tag(signed.encode()).hex()


STATES = ("online", "offline", "ended")
"""the states a status payload may name (``ended``: a chief's, once its run is over)"""
FIELD = re.compile(r"([a-z]{1,16})=([A-Za-z0-9_.:-]{1,64})")
"""one ``name=value`` field of a status"""
MAX_FIELDS = 8


@dataclass(frozen=True)
class Status:
    """A node's status: its state, incarnation (None if not given) and ``name=value`` fields (who holds the
    place: ``pid``, ``host``, ``keepalive``; a chief's ``epoch``)."""

    state: str
    incarnation: int | None = None
    fields: Mapping[str, str] = field(default_factory=dict)

    def number(self, name: str) -> int | None:
        """The field ``name`` as a non-negative integer (None: absent or not one)."""
        value = self.fields.get(name)
        return int(value) if value is not None and value.isdigit() and len(value) <= 18 else None


def status_payload(
    state: bytes,
    *,
    run_id: str,
    node: str,
    incarnation: int,
    key: FleetKey | None = None,
    fields: Mapping[str, str | int] | None = None,
) -> bytes:
    """The payload announcing ``state`` of ``node`` with ``fields`` (:data:`FIELD`), signed if ``key``."""
    pairs = " ".join(f"{k}={v}" for k, v in (fields or {}).items())
    if pairs and (len(fields or {}) > MAX_FIELDS or not all(map(FIELD.fullmatch, pairs.split(" ")))):
        raise ValueError(f"status fields {pairs[:80]!r}: at most {MAX_FIELDS} name=value of the allowed form")
    text = f"{state.decode('ascii')} {incarnation}" + (f" {pairs}" if pairs else "")
    if key is not None:
        text += " " + key.status_tag(run_id, node, state.decode("ascii"), incarnation, pairs)
    return text.encode("ascii")


def parse_status(payload: bytes, *, run_id: str, node: str, key: FleetKey | None = None) -> Status:
    """Validate a status payload; :class:`MessageRejected` if it is malformed, unsigned or forged (without a
    key, a bare ``online`` / ``offline`` is accepted too)."""
    try:
        parts = payload.decode("ascii").split(" ") if len(payload) <= 1024 else []
    except UnicodeDecodeError:
        parts = []
    if not parts or parts[0] not in STATES:
        raise MessageRejected(Reason.MALFORMED, f"status {payload[:32]!r}")
    if len(parts) > 1 and not (parts[1].isdigit() and len(parts[1]) <= 20):
        raise MessageRejected(Reason.MALFORMED, f"status incarnation {parts[1][:24]!r}")
    incarnation = int(parts[1]) if len(parts) > 1 else None
    pairs = [p for p in parts[2:] if "=" in p]
    rest = parts[2 + len(pairs) :]
    matched = [FIELD.fullmatch(p) for p in pairs]
    if len(pairs) > MAX_FIELDS or not all(matched) or len(rest) > 1 or "=" in "".join(rest):
        raise MessageRejected(Reason.MALFORMED, f"status fields {payload[:48]!r}")
    fields = {m.group(1): m.group(2) for m in matched if m is not None}
    if key is None:
        return Status(parts[0], incarnation, fields)
    if len(rest) != 1 or incarnation is None:
        raise MessageRejected(Reason.UNSIGNED, f"status {payload[:32]!r} has no signature")
    expected = key.status_tag(run_id, node, parts[0], incarnation, " ".join(pairs))
    if not hmac.compare_digest(rest[0], expected):
        raise MessageRejected(Reason.BAD_SIGNATURE, f"status of {node}")
    return Status(parts[0], incarnation, fields)
