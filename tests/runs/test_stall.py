"""A stalling unit (``--stall wK=F``): paused whole the first F of every second (shifted by a phase drawn from
the learning seed and the worker id); during a pause its env steps, its agent's work and its messages in both
directions wait until the pause ends, and nothing it computes changes (the same numbers, later). Timings on a
fake clock, computed by hand."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from fleetrl.agent.learner import Learner
from fleetrl.envs.wrappers import StalledEnv
from fleetrl.runs.factory import make_learner
from fleetrl.runs.launch import worker_specs
from fleetrl.runs.settings import RunSettings
from fleetrl.runs.spec import WorkerSpec
from fleetrl.runs.uneven import (
    STALL_PERIOD,
    Stall,
    StallSchedule,
    UnevenUnit,
    UnitConditions,
    stall_schedule,
    uneven_unit,
    unit_stall,
)
from fleetrl.transport.base import Received, Will
from fleetrl.transport.stalled import StalledTransport

# paused in [0.25, 1.0), [1.25, 2.0), … (binary fractions: the sums below are exact)
SCHEDULE = StallSchedule(0.75, 0.25)


class FakeClock:
    """Time that moves only when slept or told to."""

    def __init__(self, now: float = 0.0) -> None:
        self.now = now
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


def stall_on(clock: FakeClock, schedule: StallSchedule = SCHEDULE) -> Stall:
    return Stall(schedule, clock=clock, sleep=clock.sleep)


@pytest.mark.parametrize(
    ("now", "resumes"),
    [
        (0.0, None),  # the end of the last period's running quarter
        (0.125, None),
        (0.25, 1.0),  # a pause begins: it lasts 0.75 s
        (0.5, 1.0),
        (0.9375, 1.0),
        (1.0, None),  # running again
        (1.125, None),
        (1.25, 2.0),
        (7.5, 8.0),
        (-0.5, 0.0),  # the clock's periods run both ways
    ],
)
def test_the_pause_is_the_first_share_of_each_period_after_the_phase(
    now: float, resumes: float | None
) -> None:
    assert SCHEDULE.resumes_at(now) == resumes


def test_a_unit_that_never_stalls_is_never_paused() -> None:
    never = StallSchedule(0.0, 0.5)
    assert all(never.resumes_at(t / 8) is None for t in range(40))


def test_wait_returns_at_once_outside_a_pause_and_at_its_end_inside_one() -> None:
    clock = FakeClock(0.125)
    stall = stall_on(clock)
    assert stall.wait() == 0.0 and clock.sleeps == []
    clock.now = 0.5
    assert stall.wait() == 0.5 and clock.now == 1.0 and clock.sleeps == [0.5]
    assert stall.wait() == 0.0  # resumed: the next pause is at 1.25


def test_the_phase_comes_from_the_seed_and_the_worker() -> None:
    assert stall_schedule(0.75, 3, 2) == stall_schedule(0.75, 3, 2)
    phases = {stall_schedule(0.75, seed, worker).phase for seed in (3, 4) for worker in range(3)}
    assert len(phases) == 6 and all(0 <= p < STALL_PERIOD for p in phases)
    assert stall_schedule(0.75, 3, 2).share == 0.75
    assert unit_stall(None, seed=3, worker=2) is None
    assert unit_stall(UnitConditions(slowdown=2), seed=3, worker=2) is None
    stall = unit_stall(UnitConditions(stall=0.5), seed=3, worker=2)
    assert stall is not None and stall.schedule == stall_schedule(0.5, 3, 2)


@pytest.mark.parametrize("share", [0.2, 0.5, 0.75])
def test_a_unit_is_paused_the_share_asked_for(share: float) -> None:
    """Over 10 periods sampled every millisecond, for a few phases."""
    for worker in range(3):
        schedule = stall_schedule(share, 11, worker)
        times = np.arange(0, 10, 0.001)
        paused = np.mean([schedule.resumes_at(float(t)) is not None for t in times])
        assert paused == pytest.approx(share, abs=0.002)


class FakeInner:
    """A transport that records when (on the fake clock) each call reached it; a receive returns the message
    ``arrives`` names after ``arrives_in`` seconds (the clock moves by that much), or times out."""

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock
        self.calls: list[tuple[float, str, Any]] = []
        self.arrives: Received | None = None
        self.arrives_in = 0.0

    def connect(self, client_id: str, *, will: Will | None = None, timeout: float | None = None) -> None:
        self.calls.append((self.clock.now, "connect", client_id))

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        self.calls.append((self.clock.now, "publish", topic))

    def announce(self, topic: str, payload: bytes) -> None:
        self.calls.append((self.clock.now, "announce", topic))

    def subscribe(self, topic_filter: str, *, qos: int = 1) -> None:
        self.calls.append((self.clock.now, "subscribe", topic_filter))

    def receive(self, timeout: float | None = None) -> Received | None:
        self.calls.append((self.clock.now, "receive", timeout))
        message, self.arrives = self.arrives, None
        if message is None:
            self.clock.now += timeout or 0.0
            return None
        self.clock.now += self.arrives_in
        return message

    def close(self) -> None:
        self.calls.append((self.clock.now, "close", None))


def stalled_link(now: float) -> tuple[StalledTransport, FakeInner, FakeClock]:
    clock = FakeClock(now)
    inner = FakeInner(clock)
    return StalledTransport(inner, stall_on(clock).wait), inner, clock


def test_a_message_sent_in_a_pause_leaves_when_it_ends() -> None:
    link, inner, clock = stalled_link(0.5)
    link.publish("up/grad", b"g")
    link.announce("up/status", b"online")
    assert inner.calls == [(1.0, "publish", "up/grad"), (1.0, "announce", "up/status")]
    clock.now = 1.125  # running: at once
    link.publish("up/grad", b"g2")
    assert inner.calls[-1] == (1.125, "publish", "up/grad")


def test_a_message_that_arrives_in_a_pause_is_handed_over_when_it_ends() -> None:
    link, inner, clock = stalled_link(0.0)
    inner.arrives, inner.arrives_in = Received("down/average", b"a"), 0.5  # it reaches the unit at 0.5
    received = link.receive(timeout=5.0)
    assert received is not None and received.topic == "down/average"
    assert clock.now == 1.0  # the unit takes it when its pause ends, not at 0.5
    assert inner.calls == [(0.0, "receive", 5.0)]


def test_a_receive_in_a_pause_waits_for_its_end_and_the_pause_counts_against_the_timeout() -> None:
    link, inner, clock = stalled_link(0.75)
    assert link.receive(timeout=0.375) is None  # the pause's 0.25 s counted: 0.125 s left after it
    assert inner.calls == [(1.0, "receive", 0.125)] and clock.now == 1.125
    inner.arrives = Received("down/average", b"a")
    clock.now = 1.5  # in a pause, something already queued: read when the pause ends
    assert link.receive(timeout=None) is not None
    assert inner.calls[-1] == (2.0, "receive", None) and clock.now == 2.0


def test_the_link_passes_everything_through_outside_a_pause() -> None:
    link, inner, clock = stalled_link(0.125)
    link.connect("unit")
    link.subscribe("down/#")
    link.close()
    assert inner.calls == [(0.125, "connect", "unit"), (0.125, "subscribe", "down/#"), (0.125, "close", None)]
    assert clock.sleeps == []


class ClockedEnv:
    """A stand-in env whose every step and reset is recorded with the fake clock's time (and takes 0.1 s)."""

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock
        self.at: list[tuple[str, float]] = []

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        self.at.append(("reset", self.clock.now))
        self.clock.now += 0.125
        return 0, {}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self.at.append(("step", self.clock.now))
        self.clock.now += 0.125
        return action, 1.0, False, False, {}


def test_no_env_step_happens_in_a_pause() -> None:
    import gymnasium

    clock = FakeClock(0.0)
    inner = ClockedEnv(clock)
    env = StalledEnv.__new__(StalledEnv)  # the wrapper's own logic; a stand-in env needs no spaces
    gymnasium.Wrapper.__init__(env, gymnasium.make("CartPole-v1"))
    env.env = inner  # type: ignore[assignment]
    env._wait = stall_on(clock).wait
    env.reset()
    for k in range(3):
        env.step(k)
    # reset at 0; the step due at 0.125 runs at once (its 0.125 s ends as the pause begins); the next waits
    assert inner.at == [("reset", 0.0), ("step", 0.125), ("step", 1.0), ("step", 1.125)]


class StallOnCall:
    """A clock for a real learner: every reading moves time on by ``tick`` (so pauses come and go while the
    unit plays and computes), and a sleep moves it on by its length."""

    def __init__(self, tick: float) -> None:
        self.now = 0.0
        self.tick = tick
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        self.now += self.tick
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


def cartpole_spec(tmp_path: Any, *argv: str) -> WorkerSpec:
    from fleetrl.cli.main import build_parser
    from fleetrl.cli.settings_args import settings_from_args

    args = build_parser().parse_args(["train", "--env", "cartpole", "--out", str(tmp_path / "run"), *argv])
    settings = settings_from_args(RunSettings, args)
    return worker_specs(settings, None, "r")[1]


def test_a_stalling_unit_computes_the_same_numbers_later(tmp_path: Any) -> None:
    """A real CartPole learner played round by round, with and without pauses at every env step, reset,
    piece of work and agent call: the same episodes, losses and parameters; the stalled one slept."""
    even = make_learner(cartpole_spec(tmp_path))
    built = make_learner(cartpole_spec(tmp_path))
    clock = StallOnCall(tick=0.01)
    stall = Stall(StallSchedule(0.5, 0.1), clock=clock, sleep=clock.sleep)
    stalled_env = StalledEnv(built.env, stall.wait)
    stalled_learner = Learner(stalled_env, built.agent, built.criterion, built.seeds, built.keep_learning)
    stalled = UnevenUnit(stalled_learner, stall=stall)
    for _ in range(3):
        a, b = even.play_round(), stalled.play_round()
        assert (a.score, a.steps, a.actor_loss, a.critic_loss) == (
            b.score,
            b.steps,
            b.actor_loss,
            b.critic_loss,
        )
    # the per-step path: the agent's calls go through the wrapper (each waits out a pause first)
    played_even, played_stalled = even.begin_round(), stalled.begin_round()
    steps = even.agent.begin_update()
    assert stalled.agent.begin_update() == steps
    for k in range(steps):
        g = even.agent.step_gradients(k)
        np.testing.assert_array_equal(g, stalled.agent.step_gradients(k))
        even.agent.apply_step(g)
        stalled.agent.apply_step(g)
    even.end_round(played_even, even.agent.end_update())
    stalled.end_round(played_stalled, stalled.agent.end_update())
    np.testing.assert_array_equal(even.agent.model_parameters(), stalled_learner.agent.model_parameters())
    assert len(clock.sleeps) >= 3  # it did pause, several times


def test_a_stalling_unit_is_wrapped_and_its_spec_carries_the_stall(tmp_path: Any) -> None:
    spec = cartpole_spec(tmp_path, "--stall", "w1=0.75")
    assert spec.uneven == UnitConditions(stall=0.75)
    assert WorkerSpec.from_json(spec.to_json()) == spec  # what a worker process is handed
    learner = make_learner(spec)
    assert isinstance(learner.env, StalledEnv)
    wrapped = uneven_unit(learner, spec.uneven, seed=spec.learning.seed, worker=spec.worker)
    assert isinstance(wrapped, UnevenUnit) and wrapped.stall is not None
    assert wrapped.stall.schedule == stall_schedule(0.75, spec.learning.seed, 1)
    assert not isinstance(make_learner(cartpole_spec(tmp_path)).env, StalledEnv)
