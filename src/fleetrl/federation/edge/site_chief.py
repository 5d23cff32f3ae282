"""The members' side of an edge aggregator: :class:`SiteChief` is a :class:`~.chief.machine.Chief` of the
site's run whose closing an exchange means adding its members' answers up (float64, in sorted member order,
weighted by their units) into one message for the root, and whose answers are the root's, passed down with
member ids; members' welcomes wait for the root's.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from fleetrl.federation.aggregation import weighted_sum
from fleetrl.federation.chief.answer import ClosedExchange, welcome_step
from fleetrl.federation.chief.machine import Chief
from fleetrl.federation.events import ChiefEvent, ChiefStep
from fleetrl.federation.plan import ChiefPlan
from fleetrl.federation.schemes import COMPLETED
from fleetrl.federation.shared_settings import settings_difference
from fleetrl.federation.wire.messages import Message
from fleetrl.federation.wire.topics import CHIEF_ID, validate_id, validate_worker_id

__all__ = ["SiteChief"]


class SiteChief(Chief):
    """A :class:`~.chief.machine.Chief` of a site's members whose exchanges are answered by the root.

    :param site_id: the site's worker id at the root.  :param root_run: the root's run id.
    :param plan: the site's run (``run_id``: the site's; ``workers``: its members).
    :param chief_options: :class:`~.chief.machine.Chief`'s others.
    """

    def __init__(self, plan: ChiefPlan, *, site_id: str, root_run: str, **chief_options: Any) -> None:
        """A site that the root has not welcomed yet."""
        super().__init__(plan, **chief_options)
        self.site_id = validate_worker_id(site_id)
        self.root_run = validate_id(root_run, "root run id")
        self.welcomed = False
        """the root has welcomed the site: members are welcomed too"""
        self.upward: list[Message] = []
        """messages for the root, taken by :class:`~.edge.aggregator.EdgeAggregator` after every input"""
        self.awaiting: tuple[ClosedExchange, dict[str, Message]] | None = None
        """the exchange sent up (who answered, what was summed), until the root answers it"""
        self._held = False  # a member asked for a welcome before the root's
        self.refused = False
        """the root refused the site's settings (the run ended for its members)"""

    # ---- the members' side: the chief's rules, welcomes held until the root's ----

    def status(self, worker: str, payload: bytes, *, retained: bool = False, now: float) -> ChiefStep:
        """As :meth:`.Chief.status`; the welcome waits for the root's."""
        return self._hold(super().status(worker, payload, retained=retained, now=now))

    def receive(self, message: Message, *, now: float) -> ChiefStep:
        """As :meth:`.Chief.receive`; a new member's welcome waits for the root's."""
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
        last_step = exchange == self.steps_per_round - 1
        closed = ClosedExchange.of(rnd, self._pending, self.state.members)
        answers = {w: self._pending[w] for w in closed.answered}
        self._waits.closed(self.state.pace, set(self.state.members), closed.answered, last_step)
        answers = self._waits.averaged(self.state.pace, answers, exchange)
        vectors = [m.flat for m in answers.values() if m.flat is not None]
        total, weight = weighted_sum(
            vectors, [float(m.units) for m in answers.values()], summed=[m.summed for m in answers.values()]
        )
        done = set(self.state.completed) | set(closed.completed)
        complete = bool(self.state.members) and self.state.members <= done
        scores = list(closed.scores.values())
        up = Message(
            COMPLETED if complete else self.scheme.round_message, self.root_run, self.site_id, rnd,
            flat=total, step=exchange, samples=sum(m.samples for m in answers.values()),
            units=round(weight),
            staleness=min(m.staleness for m in answers.values()), summed=True,
            metrics={"score": float(np.mean(scores))} if scores else {},
        )  # fmt: skip
        for worker in closed.completed:  # from any exchange of the round, as at the root
            self.state.completed.setdefault(worker, rnd)
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
        """The root welcomed the site: take the fleet's model, configuration and open exchange, and welcome
        the members that asked meanwhile."""
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
