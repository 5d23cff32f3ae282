"""An edge aggregator (a site's gateway) as a pure state machine: a chief to its members
(:class:`~.edge.site_chief.SiteChief`), whose exchanges go up as one float64 sum, and one worker to the root,
whose answers it passes down. Only a rule and a scheme whose answer is that mean can run in a tree.
docs/protocol.md, "Edge aggregators".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from fleetrl.federation.aggregation import decomposes
from fleetrl.federation.edge.site_chief import SiteChief
from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import Scheme, resolve_scheme
from fleetrl.federation.wire.messages import Message, MessageRejected, decode
from fleetrl.federation.wire.topics import CHIEF_ID

__all__ = ["TREE_SCHEMES", "EdgeAggregator", "EdgeStep", "check_tree"]

TREE_SCHEMES = ("pergrad", "fedavg")
"""schemes whose chief's answer is the aggregation rule's mean of the answers (no transfer, no server state):
the ones an edge aggregator can sum for"""


def check_tree(scheme: str | Scheme, aggregator: str) -> None:
    """ValueError, in one line, if a run of ``scheme`` and rule ``aggregator`` cannot have edge
    aggregators."""
    name = resolve_scheme(scheme).name
    if name not in TREE_SCHEMES:
        raise ValueError(
            f"scheme {name!r} cannot run behind edge aggregators (they sum their members' answers): choose "
            + " or ".join(TREE_SCHEMES)
        )
    if not decomposes(aggregator):
        raise ValueError(
            f"aggregation {aggregator!r} does not decompose into sites' sums (a robust rule needs every "
            "member's vector at one place): use mean, or run the fleet flat"
        )


@dataclass(frozen=True)
class EdgeStep:
    """What the aggregator does after one input: messages to its members (``down``, broadcast on the site's
    chief topic), to the root (``up``, on its worker topic there) and events to log."""

    down: tuple[Message, ...] = ()
    up: tuple[Message, ...] = ()
    events: tuple[ChiefEvent, ...] = ()

    def __add__(self, other: EdgeStep) -> EdgeStep:
        """Both steps, this one first."""
        return EdgeStep(self.down + other.down, self.up + other.up, self.events + other.events)


class EdgeAggregator:
    """A site's edge aggregator (see the module's docstring).

    :param plan: the site's run (its ``run_id``; its ``workers``: the site's members), as its members' chief
        sees it.
    :param site_id: its worker id at the root.  :param root_run: the root's run id.
    :param resend_interval: seconds without the root's answer (or welcome) before the site re-sends.
    :param chief_options: the members' chief's others (:class:`~.chief.machine.Chief`'s ``key``,
        ``fleet_model`` …). Under a per-step scheme give it a ``fleet_model`` (``fleetrl aggregator`` does): a
        member that joins after the first exchange is welcomed with the fleet's model as it is then; without
        one, with the root's welcome's.
    """

    def __init__(
        self,
        plan: ChiefPlan,
        *,
        site_id: str,
        root_run: str,
        resend_interval: float = 5.0,
        **chief_options: Any,
    ) -> None:
        """The aggregator, not yet started (:meth:`start`)."""
        check_tree(plan.scheme, plan.aggregator)
        self.site = SiteChief(plan, site_id=site_id, root_run=root_run, **chief_options)
        self.resend_interval = resend_interval
        self._last_up: Message | None = None
        self._next_send = math.inf

    @property
    def finished(self) -> bool:
        """The site's run has ended (the root's ``done``, its refusal, or every member gone)."""
        return self.site.finished

    def start(self, *, now: float) -> EdgeStep:
        """Join the root: the ``join`` with the site's shared settings (re-sent until the welcome)."""
        site = self.site
        join = Message("join", site.root_run, site.site_id, 1, settings=site.settings or {})
        return self._up(EdgeStep(up=(join,)), now)

    # ---- from the members ----

    def receive_bytes(self, payload: bytes, *, topic_worker: str | None = None, now: float) -> EdgeStep:
        """A payload on a member's topic (:meth:`.Chief.receive_bytes`)."""
        return self._from(self.site.receive_bytes(payload, topic_worker=topic_worker, now=now), now)

    def status(self, worker: str, payload: bytes, *, retained: bool = False, now: float) -> EdgeStep:
        """A member's status payload (:meth:`.Chief.status`)."""
        return self._from(self.site.status(worker, payload, retained=retained, now=now), now)

    # ---- from the root ----

    def root_bytes(self, payload: bytes, *, now: float) -> EdgeStep:
        """A payload on the root's chief topic; a defect is an event, never an exception."""
        site = self.site
        try:
            message = decode(
                payload, run_id=site.root_run, known_senders=(CHIEF_ID,), layout=site.layout, key=site.key,
                layouts={"welcome": site.welcome_layout, "done": site.welcome_layout},
            )  # fmt: skip
        except MessageRejected as exc:
            event = ChiefEvent("rejected", site.round, sender=CHIEF_ID, reason=exc.reason, detail=exc.detail)
            return EdgeStep(events=(event,))
        return self.from_root(message, now=now)

    def from_root(self, message: Message, *, now: float) -> EdgeStep:
        """A decoded message of the root chief: its welcome, an answer, ``done`` or a refusal."""
        site = self.site
        if message.type == "welcome":
            step = site.root_welcome(message, now=now)
            if site.welcomed and self._last_up is not None and self._last_up.type == "join":
                self._last_up, self._next_send = None, math.inf
            return self._from(step, now)
        if message.type == "refused" and site.site_id in message.finished:
            return self._from(site.root_refused(message.detail), now)
        if message.type == "done":
            return self._from(site.root_done(), now)
        if message.type not in ("average", "transfer"):
            return EdgeStep()
        last = self._last_up
        if (
            last is not None
            and last.type != "join"
            and (message.round, message.step) >= (last.round, last.step)
        ):
            self._last_up, self._next_send = None, math.inf  # answered: nothing more to re-send
        return self._from(site.root_answer(message, now=now), now)

    # ---- time ----

    def tick(self, now: float) -> EdgeStep:
        """Deadlines: the members' (dropouts, an exchange's grace) and the re-send of what the root has not
        answered."""
        step = self._from(self.site.tick(now), now)
        if self._last_up is not None and now >= self._next_send and not self.finished:
            self._next_send = now + self.resend_interval
            step += EdgeStep(up=(self._last_up,))
        return step

    def next_deadline(self) -> float | None:
        """When :meth:`tick` may next change something, or None."""
        if self.finished:
            return None
        times = [t for t in (self.site.next_deadline(), self._next_send) if t is not None and t < math.inf]
        return min(times, default=None)

    def _from(self, step: ChiefStep, now: float) -> EdgeStep:
        """The members' chief's step, with what it has for the root."""
        up, self.site.upward = tuple(self.site.upward), []
        return self._up(EdgeStep(step.outgoing, up, step.events), now)

    def _up(self, step: EdgeStep, now: float) -> EdgeStep:
        if step.up:
            self._last_up, self._next_send = step.up[-1], now + self.resend_interval
        return step
