"""The speed-loop task on a fleet of DC motors, as a Gymnasium env; the fleet's unit factory; the driver a
device bridge serves.

``factory(unit, fleet_seed, link=None)`` is what ``fleetrl train --env fleet_dc_motor.units:factory`` calls
to build each worker's unit. The env owns the task — the speed setpoints, the observation it composes, the
reward and the episode's end; the motor's physics is :class:`fleet_dc_motor.motor.DCMotor`, which the env
only commands (``[duty]``) and reads (``[speed, current]``) through a ``fleetrl.link.base.DeviceLink``:
in-process by default, or a device bridge over MQTT serving ``driver(unit, fleet_seed, realtime=...)``
(``--device-link mqtt --device-driver fleet_dc_motor.units:driver``). Both give the same scores.

Each episode lasts :data:`EPISODE_STEPS` control periods of 10 ms (2 s). The setpoint is drawn at the
reset, and again at :data:`SWITCH_STEP` (a step change), each of a random sign and a magnitude of
U(0.2, 0.8) × :data:`RATED_SPEED`. The reward of a step is ``−|setpoint − speed| / RATED_SPEED`` (the speed
as measured at the step's end against the setpoint the agent saw), so a score of −S over an episode is a
mean tracking error of S / 200 of the rated speed.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium
import numpy as np

from fleet_dc_motor.motor import CONTROL_PERIOD, DCMotor, unit_params
from fleetrl.link.base import DeviceLink
from fleetrl.link.driver import DeviceDriver, DriverSpec, SimulatedDriver
from fleetrl.link.inprocess import InProcessLink

ENV_ID = "fleet_dc_motor/MotorSpeed-v0"
EPISODE_STEPS = 200
"""the episode cap: 200 control periods of 10 ms"""
SWITCH_STEP = 100
"""the step after which the second setpoint applies"""
RATED_SPEED = 200.0
"""the speed the observation and the reward are scaled by (rad/s; ≈ 1900 rpm)"""
SETPOINT_RANGE = (0.2, 0.8)
"""a setpoint's magnitude, as a fraction of the rated speed"""
TARGET_SCORE = -10.0
"""learning is complete when the weighted moving average of the last 10 scores reaches this: a mean
tracking error of 5 % of the rated speed, transients included (the untrained agent scores about −100)"""

SPEED_BOUND, ERROR_BOUND = 2.0, 3.0
"""the observation's bounds on the scaled speed and error (a measurement beyond is clipped)"""

SPEC = DriverSpec(
    "dc-motor",
    command_low=(-1.0,),
    command_high=(1.0,),
    discrete_commands=(),
    control_period=CONTROL_PERIOD,
    limit_index=0,
    limit=1.5 * RATED_SPEED,
    sensor_size=2,
    command_dtype="float32",
)
"""what a device bridge must know of a motor: the command ``[duty]`` within ±1 (continuous only), a control
period of 10 ms, the sensor vector ``[speed, current]``, and the protective stop: the bridge switches the
motor off when ``|speed|`` passes 300 rad/s, which no unit reaches on its supply (no-load speeds are at most
246 rad/s), so only a fault or a runaway trips it"""


class MotorSpeedEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """Hold one DC motor of a seeded fleet at a speed setpoint.

    Observation (float32): ``[speed, setpoint, setpoint − speed]``, each over :data:`RATED_SPEED`.
    Action (float32): ``[duty]`` in ``[−1, 1]``, the H-bridge's duty cycle (the voltage as a fraction of the
    12 V supply). The env never terminates an episode: its cap is the TimeLimit of
    ``gymnasium.make(ENV_ID)`` (:data:`EPISODE_STEPS`).

    :param unit: which unit of the fleet (its constants drawn from ``(unit, fleet_seed)``)
    :param fleet_seed: the fleet
    :param link: how to reach the motor (None: simulate unit ``unit`` of fleet ``fleet_seed`` in-process)
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's own attribute)
    sensor_size = SPEC.sensor_size
    """the length of the measurement the link returns (the observation is composed from it: fleetrl checks a
    driver's sensor vector against this)"""

    def __init__(self, unit: int = 0, fleet_seed: int = 0, link: DeviceLink | None = None) -> None:
        self.unit = unit
        self.fleet_seed = fleet_seed
        self.link = link or InProcessLink(DCMotor(unit_params(unit, fleet_seed)))
        low = np.array([-SPEED_BOUND, -1.0, -ERROR_BOUND], dtype=np.float32)
        self.observation_space = gymnasium.spaces.Box(low, -low, dtype=np.float32)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.setpoints = (0.0, 0.0)
        """this episode's two setpoints (rad/s)"""
        self.steps = 0
        self.setpoint = 0.0
        """the setpoint in force (rad/s)"""

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """A new episode: two setpoints and the motor's reset seed drawn from the env's generator."""
        super().reset(seed=seed)
        rng = self.np_random
        low, high = SETPOINT_RANGE
        signs = rng.choice([-1.0, 1.0], size=2)
        first, second = (float(sign * rng.uniform(low, high) * RATED_SPEED) for sign in signs)
        self.setpoints = (first, second)
        self.steps = 0
        self.setpoint = self.setpoints[0]
        measured = self.link.reset(int(rng.integers(2**63)))
        return self._observe(measured), self._info(measured)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control period at duty ``action[0]`` (beyond ±1 the H-bridge saturates); the reward judges the
        speed reached against the setpoint the agent saw."""
        duty = np.asarray(action, dtype=np.float32).reshape(-1)
        if duty.shape != (1,) or not math.isfinite(duty[0]):
            raise ValueError(f"the action must be one finite duty cycle, got {action!r}")
        measured, extras = self.link.step(duty)
        reward = -abs(self.setpoint - float(measured[0])) / RATED_SPEED
        self.steps += 1
        self.setpoint = self.setpoints[1] if self.steps >= SWITCH_STEP else self.setpoints[0]
        return self._observe(measured), reward, False, False, {**extras, **self._info(measured)}

    def close(self) -> None:
        """Release the motor (over a bridge: disconnect; its watchdog switches the motor off)."""
        self.link.close()

    def _observe(self, measured: np.ndarray) -> np.ndarray:
        speed = float(np.clip(measured[0] / RATED_SPEED, -SPEED_BOUND, SPEED_BOUND))
        setpoint = self.setpoint / RATED_SPEED
        error = float(np.clip(setpoint - speed, -ERROR_BOUND, ERROR_BOUND))
        return np.array([speed, setpoint, error], dtype=np.float32)

    def _info(self, measured: np.ndarray) -> dict[str, Any]:
        return {"speed": float(measured[0]), "current": float(measured[1]), "setpoint": self.setpoint}


def register() -> None:
    """Register :data:`ENV_ID` with Gymnasium (its cap and target); calling again is harmless."""
    if ENV_ID not in gymnasium.envs.registration.registry:
        gymnasium.register(
            id=ENV_ID,
            entry_point="fleet_dc_motor.units:MotorSpeedEnv",
            max_episode_steps=EPISODE_STEPS,
            reward_threshold=TARGET_SCORE,
        )


def factory(
    unit: int, fleet_seed: int, link: DeviceLink | None = None
) -> gymnasium.Env[np.ndarray, np.ndarray]:
    """Unit ``unit`` of fleet ``fleet_seed``: the speed-loop env on that unit's motor, simulated in-process or
    reached through ``link``, capped at :data:`EPISODE_STEPS` steps (``fleetrl train --env
    fleet_dc_motor.units:factory``)."""
    register()
    return gymnasium.make(ENV_ID, unit=unit, fleet_seed=fleet_seed, link=link)


def driver(unit: int, fleet_seed: int, *, realtime: bool = False) -> DeviceDriver:
    """The device side a bridge serves (``--device-driver fleet_dc_motor.units:driver``, ``fleetrl device
    --driver ...``): unit ``unit`` of fleet ``fleet_seed`` simulated, in lockstep or paced by the wall clock
    (``realtime``). A real motor's driver function would open its hardware here instead."""
    return SimulatedDriver(DCMotor(unit_params(unit, fleet_seed)), SPEC, realtime=realtime)
