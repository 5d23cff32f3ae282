"""Time on the rigs: what a fleet would spend on real-time hardware until its units complete.

A simulated run costs rounds; a fleet of real units costs time, each step one control period of its unit
(QUBE-Servo 2: 6 ms; CartPole: 20 ms). How rounds become time depends on who waits for whom:

* **synchronous** (a federation scheme with a round barrier): a round closes when its last member has played
  its episode, so round r lasts as long as the longest episode played in it, ``max_w steps[w][r] × period``;
  a unit has spent the rounds up to the one in which its criterion held (under a quorum a straggler's
  episodes count in the round it contributed to, and a round the fleet closed without it lasts as long as
  its members' episodes);
* **alone** (each unit trains by itself): a unit plays its episodes back to back, ``Σ_r steps[u][r] ×
  period``; the fleet is done when its slowest unit is;
* **asynchronous** (a scheme without a round barrier, ``fedasync``): no unit waits for another, so each plays
  back to back as alone (its rounds are its own count), the fleet done when its slowest unit is.

Only the episodes count: the device-side reset between episodes (the QUBE's swing-up) and the learner's
updates are left out, the same for every rule. A unit that never completed counts all the rounds it played
(a lower bound, flagged by :attr:`RigTime.complete`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

from fleetrl.federation.schemes import Granularity, scheme_class

WaitingRule = Literal["synchronous", "alone", "asynchronous"]
"""how a fleet's units wait for each other (see the module docstring)"""


@dataclass(frozen=True)
class RigTime:
    """Seconds on real-time rigs until the fleet, and each unit, completed."""

    fleet: float
    """until the last unit completed (or played its last round)"""
    per_unit: dict[str, float]
    """unit → until its own criterion held (or it played its last round)"""
    complete: bool
    """every unit completed (False: the figures are lower bounds)"""

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready account, rounded to milliseconds."""
        return {
            "fleet": round(self.fleet, 3),
            "per_unit": {unit: round(s, 3) for unit, s in self.per_unit.items()},
            "complete": self.complete,
        }


def _by_round(played: Mapping[int, int] | Sequence[int]) -> dict[int, int]:
    """Round → steps (a sequence: rounds 1, 2, … in order)."""
    return dict(played) if isinstance(played, Mapping) else {i + 1: s for i, s in enumerate(played)}


def rig_time(
    steps: Mapping[str, Mapping[int, int] | Sequence[int]],
    completed_at: Mapping[str, int | None],
    period: float,
    rule: WaitingRule,
) -> RigTime:
    """The time on the rigs of one run.

    :param steps: unit → the steps of each round it played: round → steps, or a sequence for rounds 1, 2, …
        (a unit that left the fleet, or a straggler, has fewer rounds than the others).
    :param completed_at: unit → the round in which its criterion held, None if it never did.
    :param period: seconds per step (the unit type's control period).
    :param rule: who waits for whom.
    """
    if period <= 0:
        raise ValueError(f"control period {period!r}: must be > 0")
    if set(steps) != set(completed_at):
        raise ValueError(f"units with steps {sorted(steps)} != units with completions {sorted(completed_at)}")
    by_round = {unit: _by_round(played) for unit, played in steps.items()}
    last: dict[str, int] = {}
    for unit, played in by_round.items():
        done = completed_at[unit]
        last[unit] = max(played, default=0) if done is None else done
        if last[unit] > max(played, default=0):
            raise ValueError(
                f"unit {unit} completed at round {last[unit]} but played up to round {max(played, default=0)}"
            )
    if rule in ("alone", "asynchronous"):
        per_unit = {
            u: sum(s for r, s in played.items() if r <= last[u]) * period for u, played in by_round.items()
        }
        fleet = max(per_unit.values(), default=0.0)
    elif rule == "synchronous":
        rounds = max(last.values(), default=0)
        durations = [max((p.get(i + 1, 0) for p in by_round.values()), default=0) for i in range(rounds)]
        elapsed = [0.0]
        for duration in durations:
            elapsed.append(elapsed[-1] + duration * period)
        per_unit = {u: elapsed[last[u]] for u in steps}
        fleet = elapsed[-1]
    else:
        raise ValueError(f"unknown waiting rule {rule!r} (choose synchronous, alone or asynchronous)")
    complete = all(c is not None for c in completed_at.values())
    return RigTime(fleet, per_unit, complete)


def waiting_rule(mode: str | None, scheme: str | None = None) -> WaitingRule:
    """The waiting rule of a run's mode and federation scheme (its name): ``individual`` units play alone, a
    fleet under an asynchronous scheme waits for nobody, any other federated fleet waits for each round's
    slowest member."""
    if mode == "individual":
        return "alone"
    if scheme is not None:
        try:
            if scheme_class(scheme).granularity is Granularity.ASYNC:
                return "asynchronous"
        except ValueError:  # a user's scheme that no longer imports: its records were synchronous
            pass
    return "synchronous"
