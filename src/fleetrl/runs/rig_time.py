"""Time on the rigs: what a fleet would spend on real-time hardware until its units complete (a unit's clock
runs while it plays, is reset, is absent and waits for the fleet; docs/benchmarks.md, "Time on the rigs")."""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from fleetrl.devices.factory import make_device
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.envs.catalog import get_env_spec
from fleetrl.federation.chief.stragglers import GRACE_FLOOR, GRACE_SHARE, quorum_count
from fleetrl.federation.schemes import RoundScheme, scheme_class
from fleetrl.runs.uneven import absences

RESET_SAMPLES = 10
"""seeded resets (seeds 0 … 9) whose mean is a QUBE unit's reset time"""
CONTROLLED_SHARES = (50, 90, 100)
"""the shares of a fleet's units, in per cent, a summary gives the time until they were controlled"""


def units_for(percent: int, units: int) -> int:
    """How many of ``units`` units make ``percent`` % of them, rounded up, in integers (7 % of 100 is 7)."""
    if not 0 <= percent <= 100:
        raise ValueError(f"share {percent!r} %: must be 0 … 100")
    return -(-percent * units // 100)


@dataclass(frozen=True)
class Waits:
    """Who waits for whom: a round barrier or none; under a per-step scheme (``grace``), the quorum after
    which a unit that took part in the round before gets a grace, then is left behind."""

    barrier: bool
    quorum: float = 1.0
    grace: bool = False

    @property
    def rule(self) -> str:
        if not self.barrier:
            return "nobody waits"
        return f"round barrier, quorum {self.quorum:g}" if self.grace and self.quorum < 1 else "round barrier"


NO_BARRIER = Waits(barrier=False)
"""each unit alone, or an asynchronous scheme: nobody waits"""


@dataclass(frozen=True)
class UnitPlay:
    """What one unit played: round → steps (a sequence: rounds 1, 2, …), the round its criterion held in,
    seconds of reset before each episode, round → episodes (None: one each), and before its own 2nd, 3rd, …
    round the rounds' worth it is absent."""

    steps: Mapping[int, int] | Sequence[int]
    completed_at: int | None
    reset: float = 0.0
    episodes: Mapping[int, int] | Sequence[int] | None = None
    absent: Sequence[int] = ()


@dataclass(frozen=True)
class UnitClock:
    """One unit's clock until it completed (or played its last round), in parts."""

    played: float = 0.0
    reset: float = 0.0
    absent: float = 0.0
    waited: float = 0.0

    @property
    def total(self) -> float:
        return self.played + self.reset + self.absent + self.waited


@dataclass(frozen=True)
class RigTime:
    """Seconds on real-time rigs until the fleet, and each unit, completed (or played its last round;
    ``complete`` False: the figures are lower bounds), where each unit's time went, and which completed."""

    fleet: float
    per_unit: dict[str, float]
    complete: bool
    clocks: dict[str, UnitClock] = field(default_factory=dict)
    completed: frozenset[str] = frozenset()

    def until_controlled(self, percent: int) -> float | None:
        """Seconds until ``percent`` % of the fleet's units were controlled: the k-th smallest ``per_unit`` of
        the units that completed, k = :func:`units_for`; None where fewer than k units completed."""
        need = units_for(percent, len(self.per_unit))
        if need == 0:
            return 0.0
        done = sorted(self.per_unit[unit] for unit in self.completed)
        return done[need - 1] if need <= len(done) else None

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready account, rounded to milliseconds."""
        controlled = {str(p): self.until_controlled(p) for p in CONTROLLED_SHARES}
        return {
            "fleet": round(self.fleet, 3),
            "per_unit": {unit: round(s, 3) for unit, s in self.per_unit.items()},
            "controlled": {p: None if s is None else round(s, 3) for p, s in controlled.items()},
            "complete": self.complete,
            "parts": {
                unit: {k: round(getattr(c, k), 3) for k in ("played", "reset", "absent", "waited")}
                for unit, c in self.clocks.items()
            },
        }


def _by_round(played: Mapping[int, int] | Sequence[int]) -> dict[int, int]:
    """Round → count (a sequence: rounds 1, 2, … in order)."""
    return dict(played) if isinstance(played, Mapping) else {i + 1: s for i, s in enumerate(played)}


@dataclass
class _Unit:
    """A unit's rounds (round, play seconds, reset seconds) as its clock runs through them up to ``stop``
    (the last it played up to the one its criterion held in); ``free``: when it may start its next round."""

    rounds: list[tuple[int, float, float]]
    stop: int
    absent: Sequence[int]
    free: float = 0.0
    clock: UnitClock = field(default_factory=UnitClock)


def _units(units: Mapping[str, UnitPlay], period: float) -> dict[str, _Unit]:
    built = {}
    for name, play in units.items():
        steps = _by_round(play.steps)
        episodes = _by_round(play.episodes) if play.episodes is not None else {}
        played_up_to = max(steps, default=0)
        last = played_up_to if play.completed_at is None else play.completed_at
        if last > played_up_to:
            raise ValueError(f"unit {name} completed at round {last} but played up to round {played_up_to}")
        rounds = [(r, steps[r] * period, episodes.get(r, 1) * play.reset) for r in sorted(steps)]
        built[name] = _Unit(rounds, max((r for r in steps if r <= last), default=0), play.absent)
    return built


def _play(unit: _Unit, index: int, start: float) -> float:
    """Unit's own round ``index`` from ``start``, absent first if due: when it is ready."""
    r, play, reset = unit.rounds[index]
    away = 0.0
    if index and index - 1 < len(unit.absent) and unit.absent[index - 1]:
        _, last_play, last_reset = unit.rounds[index - 1]
        away = unit.absent[index - 1] * (last_play + last_reset)
    if r <= unit.stop:
        c = unit.clock
        unit.clock = UnitClock(c.played + play, c.reset + reset, c.absent + away)
    return start + away + reset + play


def rig_time(units: Mapping[str, UnitPlay], period: float, waits: Waits) -> RigTime:
    """The time on the rigs of one run of ``units`` at ``period`` seconds per step."""
    if period <= 0:
        raise ValueError(f"control period {period!r}: must be > 0")
    built = _units(units, period)
    stopped = _barrier(built, waits) if waits.barrier else _back_to_back(built)
    clocks = {}
    for name, unit in built.items():
        c = unit.clock
        clocks[name] = UnitClock(c.played, c.reset, c.absent, max(stopped[name] - c.total, 0.0))
    completed = frozenset(name for name, play in units.items() if play.completed_at is not None)
    return RigTime(max(stopped.values(), default=0.0), stopped, completed == set(units), clocks, completed)


def _back_to_back(built: dict[str, _Unit]) -> dict[str, float]:
    """Each unit's time with nobody to wait for: its rounds back to back, up to its stop."""
    stopped = {}
    for name, unit in built.items():
        t = 0.0
        for i, (r, _, _) in enumerate(unit.rounds):
            if r > unit.stop:
                break
            t = _play(unit, i, t)
        stopped[name] = t
    return stopped


def _barrier(built: dict[str, _Unit], waits: Waits) -> dict[str, float]:
    """Each unit's time under a round barrier: until the round it stops at closed."""
    by_round: dict[int, list[tuple[str, int]]] = {}
    for name, unit in built.items():
        for i, (r, _, _) in enumerate(unit.rounds):
            by_round.setdefault(r, []).append((name, i))
    closed, before = 0.0, set(built)  # round 1 waits for every unit
    stopped = {name: 0.0 for name in built}
    for r in range(1, max((u.stop for u in built.values()), default=0) + 1):
        members = by_round.get(r, [])
        if not members:
            continue
        ready = {name: _play(built[name], i, built[name].free) for name, i in members}
        close = max(closed, *ready.values())
        present = before & set(ready)
        if waits.grace and before - present and present:  # a unit waited for missed it: the deadline
            need = quorum_count(waits.quorum, len(before))
            answered = sorted(ready[u] for u in present)
            if len(answered) >= need:
                opened = closed if r > 1 else min(ready.values())
                quorum_at = max(answered[need - 1], opened)
                close = max(close, quorum_at + max(GRACE_SHARE * (quorum_at - opened), GRACE_FLOOR))
        for name in ready:
            built[name].free = close
            if built[name].stop == r:
                stopped[name] = close
        closed, before = close, set(ready)
    return stopped


def waits_of(mode: str | None, scheme: str | None = None, quorum: float | None = None) -> Waits:
    """Who waits for whom in a run of ``mode`` under ``scheme`` (its name) with ``quorum``."""
    if mode == "individual":
        return NO_BARRIER
    barrier, leaves_late = RoundScheme.round_barrier, RoundScheme.leaves_late_units
    if scheme is not None:
        with contextlib.suppress(ValueError):  # a user's scheme that no longer imports: a round barrier
            kind = scheme_class(scheme)
            barrier, leaves_late = kind.round_barrier, kind.leaves_late_units
    if not barrier:
        return NO_BARRIER
    return Waits(barrier=True, quorum=1.0 if quorum is None else float(quorum), grace=leaves_late)


@functools.lru_cache(maxsize=4096)
def reset_seconds(env: str, unit: int, fleet_seed: int, fleet_profile: str | None = None) -> float:
    """A unit's reset time: a QUBE unit's mean ``last_reset_rig_seconds`` over :data:`RESET_SAMPLES` seeded
    resets; any other unit type: 0 (no time on a rig is known)."""
    try:
        spec = get_env_spec(env)
    except ValueError:
        return 0.0
    if spec.device != "qube":
        return 0.0
    device = make_device("qube", unit, fleet_seed, fleet_profile=spec.resolve_fleet_profile(fleet_profile))
    assert isinstance(device, QubeDevice)
    total = 0.0
    for seed in range(RESET_SAMPLES):
        device.reset(seed=seed)
        total += device.last_reset_rig_seconds
    return total / RESET_SAMPLES


def run_units(
    steps: Mapping[str, Mapping[int, int] | Sequence[int]],
    completed_at: Mapping[str, int | None],
    settings: Mapping[str, Any],
    *,
    episodes: Mapping[str, Mapping[int, int] | Sequence[int]] | None = None,
) -> dict[str, UnitPlay]:
    """Each worker's :class:`UnitPlay` in a run of ``settings`` (a run's config or result settings): its
    absences replayed from the learning seed and its id, its resets measured."""
    if set(steps) != set(completed_at):
        raise ValueError(f"units with steps {sorted(steps)} != units with completions {sorted(completed_at)}")
    absent = float(settings.get("absent") or 0.0)
    absent_rounds = float(settings.get("absent_rounds") or 3.0)
    env, fleet_seed = str(settings.get("env")), int(settings.get("fleet_seed") or 0)
    profile = settings.get("fleet_profile")
    plays = {}
    for worker, played in steps.items():
        drawn: list[int] = []
        if absent:
            draws = absences(absent, absent_rounds, int(settings.get("seed") or 0), int(worker))
            drawn = [next(draws) for _ in range(max(len(played) - 1, 0))]
        reset = reset_seconds(env, int(worker), fleet_seed, profile)
        per_round = None if episodes is None else episodes.get(worker)
        plays[worker] = UnitPlay(played, completed_at[worker], reset, per_round, tuple(drawn))
    return plays
