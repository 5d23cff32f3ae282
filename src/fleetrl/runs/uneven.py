"""An uneven simulated fleet (docs/usage.md, "Uneven fleets, simulated"): the :class:`UnevenFleet` setting,
each worker's :class:`UnitConditions`, and :func:`uneven_unit`, its learner slowed, absent at times and
stalling (:class:`StallSchedule`) without changing any number it computes."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from fleetrl.runs.setting_values import SettingError, label

ABSENCE_STREAM = 0xAB5E
"""the third word of an absence generator's seed ([seed, worker, this])"""
STALL_STREAM = 0x57A1
"""the third word of a stall phase's seed ([seed, worker, this])"""
STALL_PERIOD = 1.0
"""seconds of one stall cycle"""
TIMED_AGENT_CALLS = ("begin_update", "step_gradients", "apply_step", "end_update")
"""the agent's own work in a per-step round's update"""


@dataclass(frozen=True, kw_only=True)
class UnitConditions:
    """How one simulated unit is uneven (JSON-plain: a worker's spec carries it)."""

    step_seconds: float | None = None
    """wall seconds per env step (None: as fast as possible)"""
    reset_scale: float = 0.0
    """a reset lasts its time on the rig × this (0: as fast as possible)"""
    slowdown: float = 1.0
    link_delay: float = 0.0
    """seconds added to each message the unit sends"""
    absent: float = 0.0
    """the share of rounds the unit is absent"""
    absent_rounds: float = 3.0
    """the mean length of an absence, in rounds"""
    stall: float = 0.0
    """the share of each second the unit is paused whole, in [0, 1)"""


@dataclass(frozen=True, kw_only=True)
class UnevenFleet:
    """How a simulated fleet is made uneven (all off by default: as fast as possible, every unit alike and
    always present). Units are named as the live view names them: ``w0`` … (or the worker id alone)."""

    pace: float | None = None
    """step every simulated unit in real time: its control period (QUBE 6 ms, CartPole 20 ms) × this
    scale, e.g. 0.1 (unset: as fast as possible)"""
    slow: dict[str, float] = field(default_factory=dict)
    """units that compute slower, e.g. ``--slow w2=4``: worker 2 takes 4× its own computing time (a
    factor ≥ 1; the ``[slow]`` table)"""
    link_delay: dict[str, float] = field(default_factory=dict)
    """units on a slow uplink, e.g. ``--link-delay w1=0.05``: seconds added to each message worker 1 sends
    (the ``[link_delay]`` table)"""
    absent: float = 0.0
    """the share of rounds each unit is absent, in [0, 1), e.g. 0.2: it leaves at random (drawn from the
    learning seed and its worker id), pauses for some rounds' worth of its own round time, comes back"""
    absent_rounds: float = 3.0
    """with ``absent``: the mean length of one absence, in rounds (≥ 1)"""
    stall: dict[str, float] = field(default_factory=dict)
    """units that stall whole, e.g. ``--stall w2=0.75``: worker 2 is paused 0.75 of every second — its
    computing, its sends and its receives wait until the pause ends, as for a process the OS stops or a unit
    whose Wi-Fi drops (a share in [0, 1); the phase is drawn from the learning seed and the worker id; the
    ``[stall]`` table)"""

    @property
    def even(self) -> bool:
        """No setting makes the fleet uneven (every one at its default)."""
        return self == UnevenFleet()

    def resolved_uneven(self, control_period: float | None, units: int | None) -> UnevenFleet:
        """These settings checked, with units named ``wK``: a new value, or SettingError naming the first
        that cannot work. ``control_period``: the unit type's (None: not known, no pacing possible);
        ``units``: how many workers the run has (None: a standalone worker, any id)."""
        if self.pace is not None:
            if not self.pace > 0:
                raise SettingError(f"{label('pace')} = {self.pace!r}: must be > 0 (a scale of the period)")
            if control_period is None:
                raise SettingError(
                    f"{label('pace')}: this unit type declares no control period, so it cannot be paced"
                )
        slow = _per_unit("slow", self.slow, units, lambda f: f >= 1, "≥ 1 (slower, not faster)")
        delay = _per_unit("link_delay", self.link_delay, units, lambda s: s >= 0, "≥ 0 seconds")
        paused = "in [0, 1) (the share of each second paused)"
        stall = _per_unit("stall", self.stall, units, lambda s: 0 <= s < 1, paused)
        if not 0 <= self.absent < 1:
            raise SettingError(f"{label('absent')} = {self.absent!r}: must be in [0, 1) (a share of rounds)")
        if not self.absent_rounds >= 1:
            raise SettingError(f"{label('absent_rounds')} = {self.absent_rounds!r}: must be ≥ 1")
        if leave_probability(self.absent, self.absent_rounds) > 1:
            most = self.absent_rounds / (self.absent_rounds + 1)
            raise SettingError(
                f"{label('absent')} = {self.absent!r}: with absences of {self.absent_rounds:g} rounds a unit "
                f"is absent at most {most:.3g} of the rounds (raise {label('absent_rounds')})"
            )
        return replace(self, slow=slow, link_delay=delay, stall=stall)

    def for_worker(self, worker: int, control_period: float | None) -> UnitConditions | None:
        """Worker ``worker``'s conditions under these resolved settings (None: it is an even unit)."""
        name = unit_name(worker)
        step_seconds, reset_scale = None, 0.0
        if self.pace is not None and control_period is not None:
            step_seconds, reset_scale = control_period * self.pace, self.pace
        conditions = UnitConditions(
            step_seconds=step_seconds,
            reset_scale=reset_scale,
            slowdown=self.slow.get(name, 1.0),
            link_delay=self.link_delay.get(name, 0.0),
            absent=self.absent,
            absent_rounds=self.absent_rounds,
            stall=self.stall.get(name, 0.0),
        )
        return None if conditions == UnitConditions() else conditions


def unit_name(worker: int) -> str:
    """How the settings name worker ``worker`` (as the live view does): ``w2``."""
    return f"w{worker}"


def _per_unit(
    name: str, table: dict[str, float], units: int | None, fits: Callable[[float], bool], must: str
) -> dict[str, float]:
    """``table`` with its keys as ``wK`` and its values as numbers that ``fits``; else SettingError."""
    known = "w0" if units == 1 else f"w0 … w{(units or 0) - 1}"
    named: dict[str, float] = {}
    for key, value in table.items():
        text = str(key).strip()
        digits = text[1:] if text[:1] == "w" else text
        if not digits.isdigit() or (units is not None and int(digits) >= units):
            fleet = f" (this fleet: {known})" if units is not None else " (a worker as wK)"
            raise SettingError(f"{label(name)} {key}={value}: unknown unit {key!r}{fleet}")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SettingError(f"{label(name)} {key}={value!r}: expected a number")
        named[unit_name(int(digits))] = float(value)
    for unit, number in named.items():
        if not fits(number):
            raise SettingError(f"{label(name)} {unit}={number:g}: must be {must}")
    return named


def leave_probability(absent: float, absent_rounds: float) -> float:
    """The chance q that a present unit leaves before a round: q·L / (1 + q·L) = absent, L = absent_rounds."""
    return absent / (absent_rounds * (1 - absent))


def absences(absent: float, absent_rounds: float, seed: int, worker: int) -> Iterator[int]:
    """For each round after the first, the rounds' worth the unit is absent before it (0: present), a
    geometric number of mean ``absent_rounds``; the same (seed, worker) gives the same pattern."""
    rng = np.random.default_rng([seed, worker, ABSENCE_STREAM])
    leave = leave_probability(absent, absent_rounds)
    while True:
        yield int(rng.geometric(1 / absent_rounds)) if leave > 0 and rng.random() < leave else 0


@dataclass(frozen=True)
class StallSchedule:
    """A stalling unit is paused the first ``share × period`` seconds of every ``period``, shifted by
    ``phase``."""

    share: float
    phase: float
    period: float = STALL_PERIOD

    def resumes_at(self, now: float) -> float | None:
        """When the pause under way at ``now`` ends (None: not paused)."""
        into = (now - self.phase) % self.period
        paused = self.share * self.period
        return now + (paused - into) if into < paused else None


def stall_schedule(share: float, seed: int, worker: int) -> StallSchedule:
    """Worker ``worker``'s pauses at ``share``, its phase drawn from the learning seed and its id."""
    rng = np.random.default_rng([seed, worker, STALL_STREAM])
    return StallSchedule(share, float(rng.random()) * STALL_PERIOD)


class Stall:
    """A unit's pauses as it lives through them, on ``clock`` (monotonic: one clock for every process)."""

    def __init__(
        self,
        schedule: StallSchedule,
        *,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.schedule = schedule
        self._clock = clock
        self._sleep = sleep

    def wait(self) -> float:
        """Wait until the pause under way (if any) ends; the seconds waited. A sleep that ends early is
        resumed; one that overshoots into the next pause returns."""
        waited = 0.0
        now = self._clock()
        resume = self.schedule.resumes_at(now)
        while resume is not None and now < resume:
            self._sleep(resume - now)
            later = self._clock()
            waited += later - now
            now = later
        return waited


def unit_stall(conditions: UnitConditions | None, *, seed: int, worker: int) -> Stall | None:
    """The stall of a unit under ``conditions`` (None: it never stalls)."""
    if conditions is None or conditions.stall == 0:
        return None
    return Stall(stall_schedule(conditions.stall, seed, worker))


class UnevenUnit:
    """A learner that plays as an uneven unit: each piece of its own work waits out a stall's pause first
    and is followed by ``(slowdown − 1)×`` its computing time asleep; before a round it may be absent
    (``absent_for``: :func:`absences`)."""

    def __init__(
        self,
        learner: Any,
        *,
        slowdown: float = 1.0,
        absent_for: Iterator[int] | None = None,
        stall: Stall | None = None,
        clock: Callable[[], float] = time.perf_counter,
        cpu_clock: Callable[[], float] = time.thread_time,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.learner = learner
        self._cpu_clock = cpu_clock
        self.slowdown = slowdown
        self.absent_for = absent_for
        self._clock = clock
        self._sleep = sleep
        self.stall = stall
        self.agent = _TimedAgent(learner.agent, self._timed, None if stall is None else stall.wait)
        self.own_time = 0.0
        """the unit's own time in the round under way (its work, slowed; not its waits)"""
        self.last_round_time: float | None = None
        self.absences: list[tuple[int, float]] = []
        """every absence so far: (rounds' worth, seconds paused)"""

    @property
    def completed(self) -> bool:
        return bool(self.learner.completed)

    def play_round(self) -> Any:
        self._begin()
        result = self._timed(self.learner.play_round)
        self.last_round_time = self.own_time
        return result

    def begin_round(self) -> Any:
        self._begin()
        return self._timed(self.learner.begin_round)

    def end_round(self, played: Any, stats: Any) -> Any:
        result = self._timed(lambda: self.learner.end_round(played, stats))
        self.last_round_time = self.own_time
        return result

    def _begin(self) -> None:
        self.own_time = 0.0
        if self.last_round_time is None or self.absent_for is None:
            return
        rounds = next(self.absent_for)
        if rounds:
            pause = rounds * self.last_round_time
            self.absences.append((rounds, pause))
            self._sleep(pause)

    def _timed(self, work: Callable[[], Any]) -> Any:
        started = self._clock()
        if self.stall is not None:
            self.stall.wait()
        computing = self._cpu_clock()
        result = work()
        extra = (self.slowdown - 1) * (self._cpu_clock() - computing)
        if extra > 0:
            self._sleep(extra)
        self.own_time += self._clock() - started
        return result


class _TimedAgent:
    """An agent whose update steps go through ``timed``; with ``before`` (a stall's wait), every other
    method call waits on it first."""

    def __init__(
        self,
        agent: Any,
        timed: Callable[[Callable[[], Any]], Any],
        before: Callable[[], Any] | None = None,
    ) -> None:
        self._agent = agent
        self._timed_call = timed
        self._before = before
        if hasattr(agent, "set_extra_loss"):  # on the object itself: a protocol check looks it up there
            self.set_extra_loss = self._waiting(agent.set_extra_loss)

    def __getattr__(self, name: str) -> Any:
        attribute = getattr(self._agent, name)
        if name in TIMED_AGENT_CALLS:
            return lambda *args, **kwargs: self._timed_call(lambda: attribute(*args, **kwargs))
        return self._waiting(attribute) if callable(attribute) else attribute

    def _waiting(self, method: Any) -> Any:
        before = self._before
        if before is None:
            return method

        def call(*args: Any, **kwargs: Any) -> Any:
            before()
            return method(*args, **kwargs)

        return call


def uneven_unit(learner: Any, conditions: UnitConditions | None, *, seed: int, worker: int) -> Any:
    """``learner`` as the unit ``conditions`` describe, or itself when it is not slowed, never absent and
    never stalls (pacing and a stall's env steps are in its env; a link delay and a stall's messages in its
    transport)."""
    if conditions is None or (conditions.slowdown == 1 and conditions.absent == 0 and conditions.stall == 0):
        return learner
    schedule = None
    if conditions.absent:
        schedule = absences(conditions.absent, conditions.absent_rounds, seed, worker)
    stall = unit_stall(conditions, seed=seed, worker=worker)
    return UnevenUnit(learner, slowdown=conditions.slowdown, absent_for=schedule, stall=stall)
