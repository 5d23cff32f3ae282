"""A paced env: each step lasts one period of wall time, late steps are not made later, a reset lasts its time
on the rig scaled and restarts the episode's clock, and nothing the env returns changes."""

from __future__ import annotations

import time

import gymnasium
import numpy as np
import pytest

from fleetrl.devices.qube.device import HAND_RESET_SECONDS
from fleetrl.envs.catalog import get_env_spec
from fleetrl.envs.registration import CARTPOLE_UNIT_ID
from fleetrl.envs.wrappers import PacedEnv


class FakeTime:
    """A clock that only moves when slept on, or when a step's computation is said to take time."""

    def __init__(self) -> None:
        self.now = 100.0
        self.slept: list[float] = []

    def clock(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.now += seconds


class StepCost(gymnasium.Wrapper):  # type: ignore[type-arg]
    """Each step costs ``costs[k]`` seconds of the fake clock (the unit's own computation)."""

    def __init__(self, env: gymnasium.Env, fake: FakeTime, costs: list[float]) -> None:  # type: ignore[type-arg]
        super().__init__(env)
        self.fake, self.costs = fake, iter(costs)

    def step(self, action):  # type: ignore[no-untyped-def]
        self.fake.now += next(self.costs)
        return self.env.step(action)


def test_an_episode_lasts_its_steps_times_the_period_and_a_late_step_is_not_delayed() -> None:
    fake = FakeTime()
    costs = [0.001, 0.001, 0.05, 0.001, 0.001, 0.004]  # the third step overruns a 20 ms period
    env = PacedEnv(
        StepCost(gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0), fake, costs),
        0.02,
        clock=fake.clock,
        sleep=fake.sleep,
    )
    env.reset(seed=1)
    started = fake.now
    for _ in range(5):
        env.step(0)
    assert fake.slept == pytest.approx([0.019, 0.019, 0.019, 0.019])  # none after the late step
    assert fake.now - started == pytest.approx(0.02 + 0.02 + 0.05 + 0.02 + 0.02)
    fake.now += 7.0  # a long pause, then a reset: the episode's clock starts afresh (no catching up)
    env.reset()
    before = fake.now
    env.step(0)
    assert fake.now - before == pytest.approx(0.02) and fake.slept[-1] == pytest.approx(0.016)


def test_pacing_changes_no_observation_or_reward() -> None:
    plain = gymnasium.make(CARTPOLE_UNIT_ID, unit=1, fleet_seed=0)
    fake = FakeTime()
    paced = PacedEnv(
        gymnasium.make(CARTPOLE_UNIT_ID, unit=1, fleet_seed=0), 0.01, clock=fake.clock, sleep=fake.sleep
    )
    a, _ = plain.reset(seed=3)
    b, _ = paced.reset(seed=3)
    assert np.array_equal(a, b)
    for action in [0, 1, 1, 0, 1, 0, 0, 1]:
        assert [np.asarray(x).tolist() for x in plain.step(action)[:4]] == [
            np.asarray(x).tolist() for x in paced.step(action)[:4]
        ]
    assert fake.now - 100.0 == pytest.approx(8 * 0.01)


def test_a_real_episode_takes_at_least_its_steps_times_the_period() -> None:
    env = PacedEnv(gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0), 0.005)
    env.reset(seed=0)
    started, steps, done = time.monotonic(), 0, False
    while not done and steps < 40:
        _, _, terminated, truncated, _ = env.step(steps % 2)
        done, steps = terminated or truncated, steps + 1
    elapsed = time.monotonic() - started
    assert elapsed >= 0.95 * steps * 0.005  # loose: a loaded machine only makes it later
    assert elapsed < steps * 0.005 + 2.0


def test_a_period_must_be_positive() -> None:
    with pytest.raises(ValueError, match="period must be > 0"):
        PacedEnv(gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0), 0.0)


class ResetCost(gymnasium.Wrapper):  # type: ignore[type-arg]
    """A reset that costs ``cost`` seconds of the fake clock and says it took ``rig`` seconds on the rig."""

    def __init__(self, env: gymnasium.Env, fake: FakeTime, cost: float, rig: float | None) -> None:  # type: ignore[type-arg]
        super().__init__(env)
        self.fake, self.cost, self.rig = fake, cost, rig

    def reset(self, **kwargs):  # type: ignore[no-untyped-def]
        self.fake.now += self.cost
        obs, info = self.env.reset(**kwargs)
        return obs, ({} if self.rig is None else {**info, "reset_seconds": self.rig})


@pytest.mark.parametrize(
    ("cost", "rig", "scale", "lasts"),
    [
        (0.1, 12.0, 0.5, 6.0),  # a swing-up of 12 s on the rig, at half the rig's time
        (0.1, 12.0, 0.0, 0.1),  # resets not paced
        (8.0, 12.0, 0.5, 8.0),  # a reset that already took longer is not made longer
        (0.1, None, 0.5, 0.1),  # a unit that reports no reset time
    ],
)
def test_a_reset_lasts_its_time_on_the_rig_times_the_scale(
    cost: float, rig: float | None, scale: float, lasts: float
) -> None:
    fake = FakeTime()
    unit = ResetCost(gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0), fake, cost, rig)
    env = PacedEnv(unit, 0.02, reset_scale=scale, clock=fake.clock, sleep=fake.sleep)
    env.reset(seed=0)
    assert fake.now - 100.0 == pytest.approx(lasts)
    before = fake.now
    env.step(0)  # the episode's clock starts when the reset returns
    assert fake.now - before == pytest.approx(0.02)


def test_a_simulated_qube_reset_says_what_it_took_on_the_rig_a_hand_reset_with_the_person() -> None:
    for unit, by_hand in ((0, False), (48, True)):  # unit 48 of table2's fleet 0: a stiff cable, by hand
        env = get_env_spec("qube").make(unit, 0, fleet_profile="table2").env
        _, info = env.reset(seed=0)
        device = env.unwrapped.link.device  # type: ignore[attr-defined]
        assert device.last_reset_by_hand == by_hand
        least = HAND_RESET_SECONDS if by_hand else 0.5
        assert info["reset_seconds"] == device.last_reset_rig_seconds >= least
        env.close()


def test_a_reset_scale_must_not_be_negative() -> None:
    with pytest.raises(ValueError, match="reset scale must be >= 0"):
        PacedEnv(gymnasium.make(CARTPOLE_UNIT_ID, unit=0, fleet_seed=0), 0.01, reset_scale=-1.0)
