"""Who belongs to a run: the workers the chief started with and, in an open fleet (the default), any unit
new to it that joins by the same handshake (docs/protocol.md, "A new unit joins"); a closed fleet takes only
its own ids.
"""

from __future__ import annotations

from collections.abc import Iterable

from fleetrl.federation.wire.topics import sorted_workers, validate_worker_id

__all__ = ["Roster"]


class Roster:
    """The run's workers, in the fixed order, and whether a new one may join.

    :param workers: the workers the run starts with (at least one).
    :param open_fleet: a worker with another valid id may join (True), or only ``workers`` take part.
    """

    def __init__(self, workers: Iterable[str], *, open_fleet: bool = True) -> None:
        """The roster of ``workers``; ValueError if there is none or an id is not valid."""
        self.workers: tuple[str, ...] = tuple(sorted_workers({validate_worker_id(w) for w in workers}))
        if not self.workers:
            raise ValueError("a run needs at least one worker")
        self.open_fleet = open_fleet

    def __contains__(self, sender: object) -> bool:
        """Whether the chief reads a message of ``sender`` at all: one of its workers, or, in an open fleet,
        any valid worker id (a new unit's ``join``)."""
        if not isinstance(sender, str):
            return False
        return sender in self.workers or (self.open_fleet and self.may_join(sender))

    def may_join(self, worker: str) -> bool:
        """``worker`` is new to the run and may join it (an open fleet, a valid worker id)."""
        if not self.open_fleet or worker in self.workers:
            return False
        try:
            validate_worker_id(worker)
        except ValueError:
            return False
        return True

    def admit(self, worker: str) -> None:
        """``worker`` is one of the run's workers from now on."""
        if not self.may_join(worker):
            raise ValueError(f"worker {worker!r} cannot join: already a worker, or the fleet is closed")
        self.workers = tuple(sorted_workers((*self.workers, worker)))
