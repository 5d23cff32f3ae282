"""An edge aggregator (a site's gateway) as a pure state machine: :class:`SiteChief`, a chief to its members
whose exchanges go up to the root as one float64 sum and whose answers are the root's, passed down; and
:class:`EdgeAggregator`, the site as one worker of the root. Only a rule and a scheme whose answer is that
mean can run in a tree (docs/protocol.md, "Edge aggregators").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from fleetrl.federation.aggregation import decomposes, weighted_sum
from fleetrl.federation.chief.answer import ClosedExchange, welcome_step
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import COMPLETED, Scheme, resolve_scheme
from fleetrl.federation.shared_settings import settings_difference
from fleetrl.federation.wire.messages import Message, MessageRejected, decode
from fleetrl.federation.wire.topics import CHIEF_ID, validate_id, validate_worker_id

__all__ = ["TREE_SCHEMES", "EdgeAggregator", "EdgeStep", "SiteChief", "check_tree"]

TREE_SCHEMES = ("pergrad", "fedavg")
"""schemes whose answer is the rule's mean of the answers (no transfer, no server state): an edge aggregator
can sum for them"""


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


class SiteChief(Chief):
    """A :class:`~.chief.machine.Chief` of a site's members (``plan``: the site's run) whose closing an
    exchange sums its members' answers (float64, in sorted member order, weighted by their units) into one
    message for the root, and whose answers are the root's; members' welcomes wait for the root's.

    :param site_id: the site's worker id at the root.  :param root_run: the root's run id.
    """

    def __init__(self, plan: ChiefPlan, *, site_id: str, root_run: str, **chief_options: Any) -> None:
        super().__init__(plan, **chief_options)
        self.site_id = validate_worker_id(site_id)
        self.root_run = validate_id(root_run, "root run id")
        self.welcomed = False  # the root has welcomed the site: members are welcomed too
        self.upward: list[Message] = []  # for the root, taken by the EdgeAggregator after every input
        self.awaiting: tuple[ClosedExchange, dict[str, Message]] | None = None  # sent up, not yet answered
        self._held = False  # a member asked for a welcome before the root's
        self.refused = False  # the root refused the site's settings (the run ended for its members)

    # ---- the members' side: the chief's rules, welcomes held until the root's ----

    def status(self, worker: str, payload: bytes, *, retained: bool = False, now: float) -> ChiefStep:
        return self._hold(super().status(worker, payload, retained=retained, now=now))

    def receive(self, message: Message, *, now: float) -> ChiefStep:
        return self._hold(super().receive(message, now=now))

    def _hold(self, step: ChiefStep) -> ChiefStep:
        if self.welcomed or not any(m.type == "welcome" for m in step.outgoing):
            return step
        self._held = True
        return ChiefStep(tuple(m for m in step.outgoing if m.type != "welcome"), step.events)

    def _all_in(self) -> bool:
        """The open exchange may close: nothing is waiting for the root, and everyone waited for answered."""
        return self.awaiting is None and super()._all_in()

    def _close_round(self, now: float) -> ChiefStep:
        """Close the open exchange at the site: its members' weighted sum goes up as one message."""
        if self.awaiting is not None or not self._pending:
            return ChiefStep()
        rnd, exchange = self.state.round, self.state.step
        closed, answers, _ = self._closing()
        vectors = [m.flat for m in answers.values() if m.flat is not None]
        total, weight = weighted_sum(
            vectors, [float(m.units) for m in answers.values()], summed=[m.summed for m in answers.values()]
        )
        complete = bool(self.state.members) and self.state.members <= set(self.state.completed)
        scores = list(closed.scores.values())
        up = Message(
            COMPLETED if complete else self.scheme.round_message, self.root_run, self.site_id, rnd,
            flat=total, step=exchange, samples=sum(m.samples for m in answers.values()), units=round(weight),
            staleness=min(m.staleness for m in answers.values()), summed=True,
            metrics={"score": float(np.mean(scores))} if scores else {},
        )  # fmt: skip
        self.awaiting, self._pending = (closed, answers), {}
        self.upward.append(up)
        event = ChiefEvent(
            "forwarded", rnd, answered=closed.answered, averaged=tuple(answers), late=closed.late,
            detail=f"step {exchange}, {round(weight)} units" + ("; complete" if complete else ""),
            remaining=self.members, scores=closed.scores,
        )  # fmt: skip
        return ChiefStep(events=(event,))

    # ---- the root's side ----

    def root_welcome(self, welcome: Message, *, now: float) -> ChiefStep:
        """The root welcomed the site: take the fleet's model, configuration and open exchange; welcome the
        members that asked meanwhile."""
        if self.welcomed or self.finished:
            return ChiefStep()
        if welcome.settings and (why := settings_difference(welcome.settings, self.settings or {})):
            return self.root_refused(why)
        self.welcomed = True
        self.state.round, self.state.step = welcome.round, welcome.step
        self.state.config = dict(welcome.config)
        self._opened_at = now
        if welcome.flat is not None:
            if self.fleet_model is not None:
                self.fleet_model.load(welcome.flat)
            self.state.model = replace(welcome, run_id=self.run_id, settings={}, config={})
        event = ChiefEvent("welcome", welcome.round, sender=self.site_id, detail="from the root")
        step = ChiefStep(events=(event,))
        if self._held:
            self._held = False
            step += welcome_step(
                self.run_id, "*", self.state.round, self.state.model, self.settings or {}, self.state.config
            )
        return step

    def root_answer(self, answer: Message, *, now: float) -> ChiefStep:
        """The root's answer (``average``) for an exchange: the members' answer for it, sent down. An answer
        for the open exchange that was not sent up (the root closed it without the site) closes it at the
        site without anyone's contribution; a copy of an answer already passed on changes nothing."""
        at, open_at = (answer.round, answer.step), (self.state.round, self.state.step)
        if self.finished or not self.welcomed or at < open_at or answer.flat is None:
            return ChiefStep()
        closed, answers = self.awaiting or (ClosedExchange.of(answer.round, {}, self.state.members), {})
        last_step = answer.step == self.steps_per_round - 1
        if self.awaiting is None:  # the root went on without the site: its members' answers are late
            self._waits.closed(self.state.pace, set(self.state.members), (), last_step)
        contributed = self.site_id in answer.contributors
        behind = tuple(answers) if contributed else ()
        reply = Message(
            answer.type, self.run_id, CHIEF_ID, answer.round, flat=answer.flat, step=answer.step,
            contributors=behind, finished=self.members if self.site_id in answer.finished else (),
            samples=sum(answers[w].samples for w in behind), units=sum(answers[w].units for w in behind),
            config=answer.config,
        )  # fmt: skip
        if answer.config:
            self.state.config = dict(answer.config)
        if self.fleet_model is not None:
            self.fleet_model.apply(reply)
        elif not self.scheme.shared_start and self.welcome_layout == self.layout:
            self.state.model = reply  # fedavg's average is the fleet's model (pergrad's: the chief's copy's)
        self.awaiting, self._pending = None, {}
        self.state.answers.broadcast(reply, self.all_workers, now)
        if last_step:
            self.state.step, self.state.round = 0, answer.round + 1
        else:
            self.state.round, self.state.step = answer.round, answer.step + 1
        self._opened_at = now
        if self.fleet_model is not None:  # a joining worker takes it as it now is
            self.state.model = self.fleet_model.welcome(self.run_id, self.state.round, self.state.step)
        event = ChiefEvent(
            "averaged", answer.round, answered=closed.answered, averaged=behind, late=closed.late,
            detail="the root's answer", remaining=self.members, scores=closed.scores,
        )  # fmt: skip
        return ChiefStep((reply,), (event,))

    def root_done(self) -> ChiefStep:
        """The root ended the run: ``done`` to the members."""
        return ChiefStep() if self.finished else self._end("the root ended the run")

    def root_refused(self, why: str) -> ChiefStep:
        """The root refused the site's settings (``why``): the site's run ends, ``done`` to the members."""
        if self.finished:
            return ChiefStep()
        self.refused = True
        return self._end(f"refused by the chief of run {self.root_run!r}: {why}")


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
    """A site's edge aggregator: its :class:`SiteChief` (``plan``, ``site_id``, ``root_run`` and
    ``chief_options`` are the site chief's), one worker of the root.

    :param resend_interval: seconds without the root's answer (or welcome) before the site re-sends.
    :param chief_options: under a per-step scheme give a ``fleet_model``: a member that joins after the first
        exchange is welcomed with the fleet's model as it is then (without one, with the root's welcome's).
    """

    def __init__(
        self, plan: ChiefPlan, *, site_id: str, root_run: str, resend_interval: float = 5.0,
        **chief_options: Any,
    ) -> None:  # fmt: skip
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
