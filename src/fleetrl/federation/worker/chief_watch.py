"""What a worker knows of its run's chief besides its messages: the newest chief epoch seen
(:mod:`.chief.lease`) and, from the chief's signed status, whether the run it waits to join has ended."""

from __future__ import annotations

import logging

from fleetrl.federation.plan import WorkerPlan
from fleetrl.federation.wire.messages import MessageRejected
from fleetrl.federation.wire.signing import FleetKey, parse_status
from fleetrl.federation.wire.topics import CHIEF_ID

__all__ = ["ChiefWatch"]

log = logging.getLogger(__name__)


class ChiefWatch:
    """The chief as one worker follows it."""

    def __init__(self, plan: WorkerPlan, key: FleetKey | None) -> None:
        self.plan, self.key = plan, key
        self.epoch = 0
        """the highest chief epoch seen: chief messages of an older one are ignored, and every message the
        worker sends carries it"""
        self.ended_at: float | None = None
        """when the chief's status said ``ended`` (None: it did not, or a chief came online since)"""

    def follow(self, epoch: int, what: str) -> None:
        """Follow the chief of ``epoch`` from now on if it is newer than the one followed (a takeover: the
        rounds in flight go on with the new chief, which resumed from the old one's checkpoint)."""
        if epoch > self.epoch:
            log.warning("worker %s: following the chief of epoch %d (%s)", self.plan.worker_id, epoch, what)
            self.epoch = epoch

    def status(self, payload: bytes, *, now: float, welcoming: bool) -> None:
        """The chief's status: ``offline`` is logged; ``ended`` while ``welcoming`` starts the grace after
        which the worker gives up (a run that is over); ``online`` ends that grace (the run's new chief)."""
        me, run_id = self.plan.worker_id, self.plan.run_id
        try:
            status = parse_status(payload, run_id=run_id, node=CHIEF_ID, key=self.key)
        except MessageRejected as exc:
            log.warning("worker %s: rejected the chief's status: %s", me, exc)
            return
        if (epoch := status.number("epoch")) is not None:
            self.follow(epoch, f"its status says {status.state}")
        if status.state == "online":
            self.ended_at = None
        elif status.state == "offline":
            log.warning("worker %s: the chief went offline; waiting", me)
        elif welcoming and self.ended_at is None:
            self.ended_at = now
            log.warning(
                "worker %s: the chief of run %r says the run has ended; waiting %g s for a new chief of it",
                me, run_id, self.plan.ended_grace,
            )  # fmt: skip

    def gives_up_at(self, *, welcoming: bool) -> float | None:
        """When a worker still ``welcoming`` gives up on a run its chief said has ended (None: not due)."""
        if self.ended_at is None or not welcoming:
            return None
        return self.ended_at + self.plan.ended_grace
