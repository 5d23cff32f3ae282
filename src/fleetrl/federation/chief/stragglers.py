"""Who the chief waits for at an exchange, and for how long: a once-per-round scheme's deadline and quorum
(:class:`RoundWaits`), and a per-step scheme's stragglers after DD-PPO (:class:`StepWaits`). docs/protocol.md,
"Deadline and quorum" and "Stragglers under a per-step scheme".
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from fleetrl.federation.wire.messages import Message

GRACE_SHARE = 0.25  # after the quorum, the others' grace as a share of the time the quorum took
GRACE_FLOOR = 0.25  # the shortest grace in seconds (fast simulated rounds are not cut by jitter)


def quorum_count(quorum: float, n: int) -> int:
    """⌈quorum·n⌉: how many of ``n`` make a quorum."""
    return math.ceil(quorum * n - 1e-9)


@dataclass
class FleetPace:
    """Who took part in what: the part of the chief's state (checkpointed) these rules keep."""

    behind: set[str] = field(default_factory=set)  # no part in the last round: not waited for at step 0
    participants: set[str] = field(default_factory=set)  # who answered an exchange of the open round
    late: Counter[str] = field(default_factory=Counter)  # per member: rounds that closed without it
    stale: Counter[str] = field(default_factory=Counter)  # per member: contributions left out as stale
    missed: set[str] = field(default_factory=set)
    """members that missed the last exchange that closed, not heard from since: not waited for (under a
    quorum below 1)"""

    def fields(self) -> dict[str, object]:
        """As JSON."""
        return {
            "behind": sorted(self.behind),
            "participants": sorted(self.participants),
            "late": dict(sorted(self.late.items())),
            "stale": dict(sorted(self.stale.items())),
            "missed": sorted(self.missed),
        }

    @classmethod
    def from_fields(cls, fields: Mapping[str, Any] | None) -> FleetPace:
        """From :meth:`fields` (None: a state written before stragglers were allowed for)."""
        if not fields:
            return cls()
        return cls(
            behind={str(w) for w in fields["behind"]},
            participants={str(w) for w in fields["participants"]},
            late=Counter({str(w): int(n) for w, n in fields["late"].items()}),
            stale=Counter({str(w): int(n) for w, n in fields["stale"].items()}),
            missed={str(w) for w in fields.get("missed", ())},
        )


@dataclass
class RoundWaits:
    """A once-per-round scheme's waiting rule: a round waits for every member of W; at its deadline
    (``round_timeout`` after it opened; None: none) it closes with the answers it has if ⌈quorum·|W|⌉
    answered, else the silent members leave W first."""

    quorum: float
    round_timeout: float | None

    def all_in(self, pace: FleetPace, members: set[str], step: int, pending: Mapping[str, Message]) -> bool:
        """Everyone waited for has answered (and someone has)."""
        return bool(pending) and members.issubset(pending)

    def note(
        self, pace: FleetPace, members: set[str], step: int, pending: Mapping[str, Message], now: float
    ) -> None:
        """An answer was taken at ``now`` and the exchange stays open."""

    def deadline(self, opened: float | None) -> float | None:
        """When the open exchange closes with whoever answered (None: not before everyone waited for)."""
        return None if opened is None or self.round_timeout is None else opened + self.round_timeout

    def heard(self, pace: FleetPace, worker: str) -> None:
        """``worker`` answered an exchange of the open round that had already closed (a late answer)."""

    def silent_leave(self, members: set[str], pending: Mapping[str, Message]) -> set[str]:
        """At the deadline: the members that leave W as the exchange closes."""
        answered = members.intersection(pending)
        return set() if len(answered) >= quorum_count(self.quorum, len(members)) else members - answered

    def admit(self, pace: FleetPace, worker: str) -> None:
        """``worker`` is new to the run (waited for from its next round)."""

    def excused(self, pace: FleetPace, worker: str, step: int) -> bool:
        """Whether a restarted ``worker`` that will not replay the open round is not waited for in its later
        exchanges (once per round: there are none)."""
        return False

    def averaged(self, pace: FleetPace, answers: Mapping[str, Message], step: int) -> dict[str, Message]:
        """The answers the scheme combines."""
        return dict(answers)

    def closed(self, pace: FleetPace, members: set[str], answered: tuple[str, ...], last_step: bool) -> None:
        """An exchange closed with ``answered``."""


@dataclass
class StepWaits(RoundWaits):
    """A per-step scheme's waiting rule: after ``quorum`` of those waited for answered, the rest get a grace;
    a member that missed an exchange is not waited for until heard from again; contributions staler than
    ``max_staleness`` rounds (None: no bound) are left out; ``round_timeout`` closes an exchange with whoever
    answered."""

    max_staleness: int | None = None
    quorum_at: float | None = None  # when the open exchange reached its quorum

    def waited_for(self, pace: FleetPace, members: set[str], step: int) -> set[str]:
        """The members the open exchange (``step`` of its round) waits for."""
        waited = members - pace.behind if step == 0 else members & pace.participants
        return waited - pace.missed if self.quorum < 1 else waited

    def all_in(self, pace: FleetPace, members: set[str], step: int, pending: Mapping[str, Message]) -> bool:
        """Everyone waited for has answered (and someone has)."""
        return bool(pending) and self.waited_for(pace, members, step).issubset(pending)

    def note(
        self, pace: FleetPace, members: set[str], step: int, pending: Mapping[str, Message], now: float
    ) -> None:
        """An answer was taken at ``now``: start the grace if the quorum is reached."""
        if self.quorum_at is not None:
            return
        waited = self.waited_for(pace, members, step)
        if len(waited.intersection(pending)) >= quorum_count(self.quorum, len(waited)):
            self.quorum_at = now

    def deadline(self, opened: float | None) -> float | None:
        """When the open exchange closes with whoever answered (None: not before everyone waited for)."""
        if opened is None:
            return None
        times = []
        if self.quorum_at is not None:
            times.append(self.quorum_at + max(GRACE_SHARE * (self.quorum_at - opened), GRACE_FLOOR))
        if self.round_timeout is not None:
            times.append(opened + self.round_timeout)
        return min(times, default=None)

    def heard(self, pace: FleetPace, worker: str) -> None:
        """``worker`` answered an exchange of the open round late: it is waited for again (quorum < 1)."""
        if self.quorum < 1:
            pace.missed.discard(worker)

    def silent_leave(self, members: set[str], pending: Mapping[str, Message]) -> set[str]:
        """Nobody leaves W for being late: a straggler catches up."""
        return set()

    def admit(self, pace: FleetPace, worker: str) -> None:
        """``worker`` is new to the run: behind until the round-opening exchange after its first round."""
        pace.behind.add(worker)

    def excused(self, pace: FleetPace, worker: str, step: int) -> bool:
        """A restarted ``worker`` that will not replay the open round joins the fleet's next round."""
        if step == 0:
            return False
        pace.participants.discard(worker)
        return True

    def averaged(self, pace: FleetPace, answers: Mapping[str, Message], step: int) -> dict[str, Message]:
        """The answers the scheme combines: those within ``max_staleness`` (all, if none is); at a round's
        first exchange, each one left out is counted."""
        bound = self.max_staleness
        fresh = {w: m for w, m in answers.items() if bound is None or m.staleness <= bound}
        if not fresh:
            return dict(answers)
        if step == 0:
            pace.stale.update(w for w in answers if w not in fresh)
        return fresh

    def closed(self, pace: FleetPace, members: set[str], answered: tuple[str, ...], last_step: bool) -> None:
        """An exchange closed with ``answered`` (none: a site's the root closed without it): the others
        missed it; at the round's last, who took no part in the round is behind."""
        self.quorum_at = None
        if answered:
            pace.missed = members - set(answered)
        pace.participants.update(answered)
        if last_step:
            pace.behind = members - pace.participants
            pace.late.update(pace.behind)
            pace.participants = set()
