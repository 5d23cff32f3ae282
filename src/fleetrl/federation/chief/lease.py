"""One chief per run and one process per worker id on a broker: the lease MQTT's retained statuses and last
wills give, and the chief's epoch (a chief taking over is one newer; one that sees a newer one is deposed).
docs/protocol.md, "One chief per run, one process per worker id".
"""

from __future__ import annotations

import os
import re
import socket
from datetime import UTC, datetime

from fleetrl.federation.wire.signing import Status

LEASE_FACTOR = 1.5  # the broker fires a silent client's will after this many keep-alives (MQTT 3.1.2.10)
DEFAULT_KEEPALIVE = 30  # the roles' MQTT keep-alive in seconds (``--keepalive``)


class Deposed(OSError):
    """A chief learned that a chief of a newer epoch runs its run: it stopped without acting (exit 1)."""


def holder_fields(keepalive: int, epoch: int | None = None) -> dict[str, str | int]:
    """The ``name=value`` fields of this process's status: pid, host, keep-alive (and a chief's epoch)."""
    host = re.sub(r"[^A-Za-z0-9_.:-]", "_", socket.gethostname())[:64] or "unknown"
    fields: dict[str, str | int] = {"pid": os.getpid(), "host": host, "keepalive": int(keepalive)}
    return fields if epoch is None else {"epoch": int(epoch), **fields}


def describe(status: Status) -> str:
    """``pid 12 on host h since 2024-…`` (what its status says; since: its incarnation, in UTC)."""
    pid, host = status.fields.get("pid"), status.fields.get("host")
    who = " ".join(filter(None, (f"pid {pid}" if pid else "", f"on host {host}" if host else "")))
    since = "an unknown time"
    if status.incarnation is not None:  # nanoseconds since 1970
        since = datetime.fromtimestamp(status.incarnation / 1e9, UTC).isoformat(timespec="seconds")
    return f"{who or 'a process'} since {since}"


def place_refusal(run_id: str, node: str, status: Status | None, topic: str) -> str | None:
    """The one line refusing a start in ``node``'s place (``chief`` or a worker id) of ``run_id`` when its
    retained ``status`` says a live process holds it; None: the place is free."""
    if status is None or status.state != "online":
        return None
    keepalive = status.number("keepalive")  # the broker keeps a silent holder's place LEASE_FACTOR times it
    wait = f"{LEASE_FACTOR * keepalive:g} s" if keepalive is not None else "1.5 × its keep-alive"
    epoch = status.number("epoch")
    role = "chief" if node == "chief" else f"worker {node}"
    if node == "chief":
        what = (
            f"run {run_id!r} has a live chief (epoch {epoch if epoch is not None else 0}): {describe(status)}"
        )
        then = f"once its lease ({wait} after its last word) has run out, start the new chief with --resume"
    else:
        what = f"worker id {node} of run {run_id!r} is live: {describe(status)}"
        then = f"once its lease ({wait} after its last word) has run out, start it again (with --resume)"
    return (
        f"{what}; only one {role} may run: stop that process first; if it was cut off or stopped, {then}; "
        f"if it is gone for good and its status is stale (a broker that crashed keeps it), clear it with "
        f"`mosquitto_pub -r -n -t {topic}`"
    )


def chief_epoch(*, checkpoint: int | None, retained: Status | None) -> int:
    """The epoch a starting chief takes: one more than the newest it knows of (its checkpoint's, the retained
    status's), or 0 for the first chief of a run."""
    known = [
        e for e in (checkpoint, None if retained is None else retained.number("epoch") or 0) if e is not None
    ]
    return max(known) + 1 if known else 0


def supersedes(status: Status, *, epoch: int, incarnation: int) -> bool:
    """Whether a chief status of another incarnation shows a chief newer than one of ``epoch``: a higher
    epoch, or the same epoch started later."""
    if status.incarnation is None or status.incarnation == incarnation:
        return False
    other = status.number("epoch") or 0
    return other > epoch or (other == epoch and status.incarnation > incarnation)


def deposed_line(run_id: str, epoch: int, by: str) -> str:
    """The one line of a chief that stops because a newer epoch runs its run."""
    return (
        f"run {run_id!r}: this chief (epoch {epoch}) was replaced by a newer chief ({by}); it stopped "
        "without publishing or checkpointing anything more: let the new chief run the run"
    )
