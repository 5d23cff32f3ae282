"""An uneven unit around a learner: slowed by sleeping (FACTOR − 1)× its computing time, per round and per
update step; absent before a round for k times its own last round's time, on a schedule drawn from the
learning seed and the worker id."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from fleetrl.runs.uneven import UnevenUnit, UnitConditions, absences, leave_probability, uneven_unit


class FakeClocks:
    """Wall and CPU clocks that move only when told: work costs ``cpu`` seconds of both, a sleep only wall
    time."""

    def __init__(self) -> None:
        self.wall = 0.0
        self.cpu = 0.0
        self.sleeps: list[float] = []

    def work(self, seconds: float) -> None:
        self.wall += seconds
        self.cpu += seconds

    def wait(self, seconds: float) -> None:  # a paced step's wait: the device's time, not computation
        self.wall += seconds

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.wall += seconds


class FakeAgent:
    def __init__(self, clocks: FakeClocks) -> None:
        self.clocks = clocks
        self.extra: Any = "unset"

    def begin_update(self) -> int:
        self.clocks.work(0.01)
        return 2

    def step_gradients(self, k: int) -> np.ndarray:
        self.clocks.work(0.02)
        return np.full(3, k, np.float32)

    def actor_layout(self) -> list[tuple[str, tuple[int, ...]]]:
        return [("w", (3,))]

    def set_extra_loss(self, fn: Any) -> None:
        self.extra = fn


class FakeLearner:
    """A round computes 0.1 s and waits 0.3 s on its paced device."""

    def __init__(self, clocks: FakeClocks) -> None:
        self.clocks = clocks
        self.agent = FakeAgent(clocks)
        self.completed = False
        self.played = 0

    def play_round(self) -> str:
        self.clocks.work(0.1)
        self.clocks.wait(0.3)
        self.played += 1
        return f"round {self.played}"

    def begin_round(self) -> str:
        return self.play_round()

    def end_round(self, played: str, stats: Any) -> str:
        self.clocks.work(0.05)
        return played


def unit(slowdown: float = 1.0, absent_for: Any = None) -> tuple[UnevenUnit, FakeClocks]:
    clocks = FakeClocks()
    wrapped = UnevenUnit(
        FakeLearner(clocks),
        slowdown=slowdown,
        absent_for=absent_for,
        clock=lambda: clocks.wall,
        cpu_clock=lambda: clocks.cpu,
        sleep=clocks.sleep,
    )
    return wrapped, clocks


def test_a_slow_unit_sleeps_its_extra_computing_time_after_each_round() -> None:
    slow, clocks = unit(slowdown=4)
    assert slow.play_round() == "round 1"
    assert clocks.sleeps == pytest.approx([0.3])  # (4 − 1) × 0.1 s computed; the device's 0.3 s not stretched
    assert slow.last_round_time == pytest.approx(0.1 + 0.3 + 0.3)


def test_a_slow_unit_sleeps_after_each_update_step_of_a_per_step_round() -> None:
    slow, clocks = unit(slowdown=3)
    played = slow.begin_round()
    assert slow.agent.begin_update() == 2
    assert slow.agent.step_gradients(1).tolist() == [1.0, 1.0, 1.0]
    assert slow.agent.actor_layout() == [("w", (3,))]  # not work: passed through, no sleep
    slow.agent.set_extra_loss(None)
    assert slow.learner.agent.extra is None
    slow.end_round(played, None)
    assert clocks.sleeps == pytest.approx([0.2, 0.02, 0.04, 0.1])
    assert slow.last_round_time == pytest.approx(3 * (0.1 + 0.01 + 0.02 + 0.05) + 0.3)


def test_an_even_unit_never_sleeps() -> None:
    even, clocks = unit()
    for _ in range(3):
        even.play_round()
    assert clocks.sleeps == []


def test_an_absent_unit_pauses_before_the_round_for_k_of_its_own_round_times() -> None:
    absent, clocks = unit(slowdown=2, absent_for=iter([0, 3, 0]))
    absent.play_round()  # round 1: never absent (no round time known yet)
    round_time = absent.last_round_time
    assert round_time == pytest.approx(0.1 + 0.3 + 0.1)
    absent.play_round()  # round 2: present
    clocks.sleeps.clear()
    played_before = absent.learner.played
    absent.play_round()  # round 3: absent for 3 rounds' worth first, then it plays
    assert clocks.sleeps[0] == pytest.approx(3 * round_time)
    assert absent.learner.played == played_before + 1
    assert absent.absences == [(3, pytest.approx(3 * round_time))]


def test_absences_are_drawn_reproducibly_per_seed_and_unit() -> None:
    def first(seed: int, worker: int, n: int = 300) -> list[int]:
        return list(itertools.islice(absences(0.2, 3.0, seed, worker), n))

    assert first(7, 2) == first(7, 2)
    assert first(7, 2) != first(7, 1) and first(7, 2) != first(8, 2)
    assert any(first(7, 2))


@pytest.mark.parametrize(("absent", "rounds"), [(0.2, 3.0), (0.5, 1.0), (0.1, 5.0)])
def test_units_are_absent_for_the_share_of_rounds_asked_for(absent: float, rounds: float) -> None:
    """Over many rounds and units (a property of the schedule, not of one seed's run)."""
    present = absent_rounds = 0
    lengths: list[int] = []
    for worker in range(10):
        for k in itertools.islice(absences(absent, rounds, 123, worker), 4000):
            present += 1
            absent_rounds += k
            if k:
                lengths.append(k)
    assert absent_rounds / (present + absent_rounds) == pytest.approx(absent, abs=0.03)
    assert np.mean(lengths) == pytest.approx(rounds, rel=0.1)
    assert leave_probability(absent, rounds) <= 1


def test_only_a_slowed_or_absent_unit_is_wrapped() -> None:
    learner = object()
    assert uneven_unit(learner, None, seed=0, worker=0) is learner
    paced_only = UnitConditions(step_seconds=0.002, link_delay=0.1)  # its env and transport carry those
    assert uneven_unit(learner, paced_only, seed=0, worker=0) is learner
    clocks = FakeClocks()
    wrapped = uneven_unit(FakeLearner(clocks), UnitConditions(absent=0.2), seed=0, worker=1)
    assert isinstance(wrapped, UnevenUnit) and wrapped.absent_for is not None and wrapped.slowdown == 1
