"""MQTT topic names of a federated run (what broker ACLs are written against), all under
``fleetrl/<run_id>/``: ``chief`` (chief → workers), ``worker/<worker_id>`` (worker → chief) and
``status/<node_id>`` (a node's retained status; ``offline`` is also its last will). docs/protocol.md.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

PREFIX = "fleetrl"
CHIEF_ID = "chief"
"""The chief's node id (a worker may not use it)."""
ONLINE = b"online"
OFFLINE = b"offline"
"""Status payload of a node that left (its last will, or a clean goodbye)."""
ENDED = b"ended"
"""Status payload of a chief whose run has ended (retained: a worker that starts later learns it)."""

_ID = re.compile(r"[A-Za-z0-9_.-]{1,64}")


def validate_id(value: str, what: str = "id") -> str:
    """``value`` if it is usable as one topic level (1–64 of ``A-Z a-z 0-9 _ . -``), else a ValueError
    naming ``what`` it is."""
    if not isinstance(value, str) or not _ID.fullmatch(value):
        raise ValueError(f"bad {what} {value!r}: use 1-64 characters from A-Z a-z 0-9 _ . -")
    return value


def validate_worker_id(worker_id: str) -> str:
    """``worker_id`` if valid for a worker (a valid id other than ``chief``), else a ValueError."""
    validate_id(worker_id, "worker id")
    if worker_id == CHIEF_ID:
        raise ValueError(f"bad worker id {worker_id!r}: reserved for the chief")
    return worker_id


def worker_sort_key(worker_id: str) -> tuple[int, int, str]:
    """The fixed order of workers: numeric ids numerically (2 before 10), then others by name."""
    if worker_id.isdigit():
        return (0, int(worker_id), worker_id)
    return (1, 0, worker_id)


def sorted_workers(worker_ids: Iterable[str]) -> list[str]:
    """Worker ids in the fixed order used for averaging and for choosing among simultaneous transfers."""
    return sorted(worker_ids, key=worker_sort_key)


def chief_topic(run_id: str) -> str:
    """Topic on which the chief broadcasts to all workers of ``run_id``."""
    return f"{PREFIX}/{validate_id(run_id, 'run id')}/chief"


def worker_topic(run_id: str, worker_id: str) -> str:
    """Topic on which worker ``worker_id`` sends to the chief."""
    return f"{PREFIX}/{validate_id(run_id, 'run id')}/worker/{validate_worker_id(worker_id)}"


def worker_filter(run_id: str) -> str:
    """Subscription filter matching every worker topic of ``run_id`` (the chief subscribes to it)."""
    return f"{PREFIX}/{validate_id(run_id, 'run id')}/worker/+"


def status_topic(run_id: str, node_id: str) -> str:
    """Retained online/offline status topic of ``node_id`` (``chief`` or a worker id)."""
    return f"{PREFIX}/{validate_id(run_id, 'run id')}/status/{validate_id(node_id, 'node id')}"


def status_filter(run_id: str) -> str:
    """Subscription filter matching the status of every node of ``run_id``."""
    return f"{PREFIX}/{validate_id(run_id, 'run id')}/status/+"


def _last_level(run_id: str, topic: str, middle: str) -> str | None:
    head = f"{PREFIX}/{run_id}/{middle}/"
    if not topic.startswith(head):
        return None
    rest = topic[len(head) :]
    return rest if _ID.fullmatch(rest) else None


def worker_of_topic(run_id: str, topic: str) -> str | None:
    """The worker id a worker topic of ``run_id`` belongs to, or None if ``topic`` is not one."""
    return _last_level(run_id, topic, "worker")


def node_of_status_topic(run_id: str, topic: str) -> str | None:
    """The node id a status topic of ``run_id`` belongs to, or None if ``topic`` is not one."""
    return _last_level(run_id, topic, "status")
