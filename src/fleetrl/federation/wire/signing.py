"""HMAC-SHA256 signatures of federation messages and node statuses under a fleet key (issue 7).

A signed message is ``MAGIC`` (4 bytes ``FRS1``) + HMAC-SHA256(key, ``MAGIC`` + envelope) (32 bytes) + the
msgpack envelope. The envelope carries the run id, the sender, the type and the round, so the signature binds
all four: a message cannot be moved to another run, sender or round without the key, and a byte-identical
replay is caught by the receivers' round rules (one message per (sender, round); see docs/protocol.md).

A status payload is ``<state> <incarnation>[ <name>=<value> …]`` or, signed, the same followed by
``<hex HMAC>`` over ``run_id/node/state/incarnation`` (and ``/<name>=<value> …`` when there are any). The
incarnation (nanoseconds since the epoch when the node started) grows with every restart, so a replayed
``online`` or the late will of an earlier incarnation is recognised. The ``name=value`` fields say who holds
the node's place (``pid``, ``host``, ``keepalive``) and, for the chief, its ``epoch``
(:mod:`fleetrl.federation.chief.lease`).
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from fleetrl.federation.wire.rejections import MessageRejected, Reason

MAGIC = b"FRS1"
"""First bytes of a signed message."""
SIGNATURE_BYTES = 32
"""Length of an HMAC-SHA256 tag."""
OVERHEAD = len(MAGIC) + SIGNATURE_BYTES
"""Bytes a signature adds to a message (``MAGIC`` + tag)."""
MIN_KEY_BYTES = 16
"""Shortest fleet key accepted."""


class FleetKey:
    """The secret every role of a fleet shares; signs and verifies messages and statuses.

    :param secret: at least :data:`MIN_KEY_BYTES` bytes (``fleetrl secure-config`` writes 32 random bytes as
        64 hex characters).
    """

    def __init__(self, secret: bytes) -> None:
        """Keep ``secret``; ValueError if it is too short to be a key."""
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
    """A node's status: ``online``, ``offline`` or (a chief's) ``ended``, the incarnation it belongs to
    (None if not given), and its ``name=value`` fields (who holds the place; a chief's epoch)."""

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
    """The payload announcing ``state`` (``b"online"``/``b"offline"``/``b"ended"``) of ``node`` with
    ``fields`` (names of 1–16 lower-case letters, values of 1–64 of ``A-Z a-z 0-9 _ . : -``), signed if
    ``key``."""
    pairs = " ".join(f"{k}={v}" for k, v in (fields or {}).items())
    if pairs and (len(fields or {}) > MAX_FIELDS or not all(map(FIELD.fullmatch, pairs.split(" ")))):
        raise ValueError(f"status fields {pairs[:80]!r}: at most {MAX_FIELDS} name=value of the allowed form")
    text = f"{state.decode('ascii')} {incarnation}" + (f" {pairs}" if pairs else "")
    if key is not None:
        text += " " + key.status_tag(run_id, node, state.decode("ascii"), incarnation, pairs)
    return text.encode("ascii")


def parse_status(payload: bytes, *, run_id: str, node: str, key: FleetKey | None = None) -> Status:
    """Validate a status payload; :class:`MessageRejected` if it is malformed, unsigned or forged.

    Without a key, the bare ``online`` / ``offline`` of older nodes is accepted too.
    """
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
