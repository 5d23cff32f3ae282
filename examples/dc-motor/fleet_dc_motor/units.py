"""The speed-loop task on a fleet of DC motors, as a Gymnasium env, and the fleet's unit factory.

``factory(unit, fleet_seed)`` is what ``fleetrl train --env fleet_dc_motor.units:factory`` calls to build
each worker's unit. The env owns the task — the speed setpoints, the observation it composes, the reward and
the episode's end; the motor's physics is :class:`fleet_dc_motor.motor.DCMotor`, which it only commands
(duty cycle) and reads (speed, current).

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

from fleet_dc_motor.motor import DCMotor, unit_params

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


class MotorSpeedEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """Hold one DC motor of a seeded fleet at a speed setpoint.

    Observation (float32): ``[speed, setpoint, setpoint − speed]``, each over :data:`RATED_SPEED`.
    Action (float32): ``[duty]`` in ``[−1, 1]``, the H-bridge's duty cycle (the voltage as a fraction of the
    12 V supply). The env never terminates an episode: its cap is the TimeLimit of
    ``gymnasium.make(ENV_ID)`` (:data:`EPISODE_STEPS`).

    :param unit: which unit of the fleet (its constants drawn from ``(unit, fleet_seed)``)
    :param fleet_seed: the fleet
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's own attribute)

    def __init__(self, unit: int = 0, fleet_seed: int = 0) -> None:
        self.unit = unit
        self.fleet_seed = fleet_seed
        self.motor = DCMotor(unit_params(unit, fleet_seed))
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
        measured = self.motor.reset(seed=int(rng.integers(2**63)))
        return self._observe(measured), self._info(measured)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control period at duty ``action[0]`` (clipped to [−1, 1]); the reward judges the speed reached
        against the setpoint the agent saw."""
        duty = np.asarray(action, dtype=np.float64).reshape(-1)
        if duty.shape != (1,) or not math.isfinite(duty[0]):
            raise ValueError(f"the action must be one finite duty cycle, got {action!r}")
        measured = self.motor.step(float(duty[0]))
        reward = -abs(self.setpoint - float(measured[0])) / RATED_SPEED
        self.steps += 1
        self.setpoint = self.setpoints[1] if self.steps >= SWITCH_STEP else self.setpoints[0]
        return self._observe(measured), reward, False, False, self._info(measured)

    def close(self) -> None:
        """Release the motor."""
        self.motor.close()

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


def factory(unit: int, fleet_seed: int) -> gymnasium.Env[np.ndarray, np.ndarray]:
    """Unit ``unit`` of fleet ``fleet_seed``: the speed-loop env on that unit's motor, capped at
    :data:`EPISODE_STEPS` steps (``fleetrl train --env fleet_dc_motor.units:factory``)."""
    register()
    return gymnasium.make(ENV_ID, unit=unit, fleet_seed=fleet_seed)
