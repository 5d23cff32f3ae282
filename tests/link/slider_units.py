"""A user's own continuous unit type behind device bridges, as the tests name it: ``--env
tests.link.slider_units:factory --device-link mqtt --device-driver tests.link.slider_units:driver``.

A slider is a cart on a short rail pushed by a motor: observation ``[x, x_dot]`` (2 values, not the
built-ins' 4), action a force ``Box(-1, 1, (1,))``; reward +1 while ``|x| <= 0.5``, 0 and the end beyond.
Each unit's mass is drawn from the fleet seed. It is what a user writes: the simulated physics (a
``fleetrl.link.base.Device`` taking a command vector), the env over a ``DeviceLink`` (a ``LinkEnv`` judging
each observation), the factory that takes an optional ``link``, and the driver function a bridge serves. The
other functions fail the seam's checks one way each.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from fleetrl.envs.link_env import LinkEnv, box_action
from fleetrl.link.base import DeviceLink
from fleetrl.link.driver import DeviceDriver, DriverSpec, SimulatedDriver, simulated_driver
from fleetrl.link.inprocess import InProcessLink

FACTORY = "tests.link.slider_units:factory"
DRIVER = "tests.link.slider_units:driver"
SLIDER_ID = "fleetrl-tests/Slider-v0"
PERIOD = 0.05
"""seconds of one control period"""
BAND = 0.5
"""|x| within which a step earns its reward"""
SPEC = DriverSpec("slider", (-2.0,), (2.0,), (), PERIOD, 0, 1.5, sensor_size=2, command_dtype="float32")
"""force within ±2 (the env's actions are ±1), no discrete commands, protective stop past |x| = 1.5"""


class SliderDevice:
    """One simulated slider: ``step`` takes a command vector ``[force]`` (the zero command: motor off)."""

    def __init__(self, mass: float) -> None:
        self.mass = mass
        self._state = np.zeros(2, dtype=np.float64)
        self._obs = np.zeros(2, dtype=np.float32)

    @classmethod
    def from_fleet(cls, unit: int, fleet_seed: int) -> SliderDevice:
        """Unit ``unit`` of fleet ``fleet_seed``: mass 1 kg ± 20 %."""
        return cls(float(np.random.default_rng([fleet_seed, unit, 7]).uniform(0.8, 1.2)))

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start at rest, ``x`` uniform in ±0.2 (seeded)."""
        self._state[:] = (np.random.default_rng(seed).uniform(-0.2, 0.2), 0.0)
        self._obs[:] = self._state
        return self._obs

    def step(self, command: np.ndarray) -> np.ndarray:
        """One period under ``command[0]`` newtons (semi-implicit Euler, light friction)."""
        x, v = self._state
        v += PERIOD * (float(command[0]) - 0.1 * v) / self.mass
        self._state[:] = (x + PERIOD * v, v)
        self._obs[:] = self._state
        return self._obs

    def close(self) -> None:
        """Nothing to release."""


class SliderEnv(LinkEnv):
    """Keep the slider near the rail's centre."""

    def __init__(self, unit: int = 0, fleet_seed: int = 0, link: DeviceLink | None = None) -> None:
        super().__init__(link or InProcessLink(SliderDevice.from_fleet(unit, fleet_seed)), n_actions=0)
        self.observation_space = gymnasium.spaces.Box(-5.0, 5.0, (2,), np.float32)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def link_action(self, action: object) -> np.ndarray:
        """``[force]`` as float32, clipped to the box."""
        space = self.action_space
        assert isinstance(space, gymnasium.spaces.Box)
        return box_action(action, space)

    def judge(self, obs: np.ndarray) -> tuple[float, bool]:
        """+1 while ``|x| <= BAND``; otherwise 0 and the end."""
        inside = abs(float(obs[0])) <= BAND
        return (1.0, False) if inside else (0.0, True)

    def frame(self, obs: np.ndarray) -> np.ndarray:
        """A blank picture (the tests draw nothing)."""
        return np.zeros((8, 8, 3), dtype=np.uint8)


if SLIDER_ID not in gymnasium.registry:
    gymnasium.register(SLIDER_ID, entry_point=SliderEnv, max_episode_steps=100, reward_threshold=95.0)


def factory(unit: int, fleet_seed: int, link: DeviceLink | None = None) -> gymnasium.Env[Any, Any]:
    """Unit ``unit`` of fleet ``fleet_seed``: simulated in-process, or reached through ``link``."""
    return gymnasium.make(SLIDER_ID, unit=unit, fleet_seed=fleet_seed, link=link)


def driver(unit: int, fleet_seed: int, *, realtime: bool) -> DeviceDriver:
    """The device side a bridge serves: the same simulated unit behind the driver interface."""
    return SimulatedDriver(SliderDevice.from_fleet(unit, fleet_seed), SPEC, realtime=realtime)


NOT_CALLABLE = 3


def qube_driver(unit: int, fleet_seed: int, *, realtime: bool) -> DeviceDriver:
    """A driver of another unit type: 4 sensor values and 3 discrete commands, not this env's spaces."""
    return simulated_driver("qube", unit, fleet_seed, realtime=realtime)


def wide_driver(unit: int, fleet_seed: int, *, realtime: bool) -> DeviceDriver:
    """Two sensor values as the env observes, but a command vector of 2 where the env's actions are 1."""
    spec = DriverSpec("wide", (-1.0, -1.0), (1.0, 1.0), (), PERIOD, 0, 1.5, sensor_size=2)
    return SimulatedDriver(SliderDevice.from_fleet(unit, fleet_seed), spec, realtime=realtime)


def not_a_driver(unit: int, fleet_seed: int, *, realtime: bool) -> dict[str, int]:
    """Returns something that is not a DeviceDriver."""
    return {"unit": unit}
