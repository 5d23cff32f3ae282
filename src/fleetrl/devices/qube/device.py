"""One simulated QUBE-Servo 2 unit (physics, sensor pipeline, actions and the device-side reset), and many
stepped together in one compiled call per time step, each row through the very control period a lone unit
runs (``agent_step``), so the states are equal bit for bit."""

import logging
import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from fleetrl.devices.qube.controllers import CATCH_DEGREES, controller_constants, device_reset, run_balance
from fleetrl.devices.qube.dynamics import (
    N_SENSOR,
    S_ALPHA,
    S_APPLIED,
    S_THETA,
    agent_step,
    pipeline_settings,
    sense_at_rest,
    write_observation,
)
from fleetrl.devices.qube.params import (
    ACTION_POWERS,
    POWER_TO_VOLTS,
    QubeConfig,
    QubeParams,
    QubeVariation,
    fleet_profile,
    qube_unit_params,
)

log = logging.getLogger(__name__)

ACTION_VOLTS = tuple(p * POWER_TO_VOLTS for p in ACTION_POWERS)  # of action index 0, 1, 2 (±1.44 V)
RESET_PERTURBATION = (math.radians(3.0), 0.2)  # a reset starts hanging, off by up to ±3° and ±0.2 rad/s
HAND_RESET_SECONDS = 30.0  # a person's time on the rig to put the pendulum upright after a failed swing-up
SETTLE_SECONDS = 0.2  # the readings stay inside the hand-off windows this long before the agent gets them
HAND_SETTLE_SECONDS = 5.0  # a pendulum put upright by hand must settle within this long


class DeviceResetError(RuntimeError):
    """The device-side swing-up did not settle the pendulum in time."""


class QubeDevice:
    """A QUBE unit as the agent's side sees it: a command in, encoder readings and velocity estimates out."""

    def __init__(self, params: QubeParams, config: QubeConfig | None = None) -> None:
        self.params = params
        self.config = config or QubeConfig()
        cfg = self.config
        self._coefficients = params.coefficients()
        self._state = np.zeros(4, dtype=np.float64)
        self._sensor = np.zeros(N_SENSOR, dtype=np.float64)
        self._obs = np.zeros(4, dtype=np.float32)

        def settings(period: float, velocity_filter: float | None) -> np.ndarray:
            return pipeline_settings(
                period,
                cfg.max_substep,
                quantise=cfg.quantise,
                velocity_filter=velocity_filter,
                delay=cfg.actuation_delay,
                max_volts=cfg.max_volts,
            )

        filter_cutoff = cfg.velocity_cutoff if cfg.velocity_estimate == "filter" else None
        self._agent_settings = settings(cfg.control_period, filter_cutoff)
        # the device's own controllers always read velocities through Quanser's filter
        self._device_settings = settings(cfg.device_period, cfg.velocity_cutoff)
        self._controllers = controller_constants()
        self.last_reset_seconds = math.nan  # simulated seconds the last device-side reset took
        self.last_reset_arm_travel = math.nan  # largest |arm angle| reading (rad) during the last reset
        self.last_reset_by_hand = False  # the last swing-up did not settle in time: put upright by hand
        self.last_unsettled = ""  # why the last reset needed a hand (:func:`unsettled_reason`)
        self.hand_resets = 0  # resets so far whose pendulum was put upright by hand
        self.name = "a QUBE unit"  # how the log names this unit

    @classmethod
    def from_fleet(
        cls,
        unit: int,
        fleet_seed: int,
        config: QubeConfig | None = None,
        variation: QubeVariation | None = None,
        *,
        profile: str | None = None,
    ) -> "QubeDevice":
        """Unit ``unit`` of fleet ``fleet_seed``, drawn with ``variation`` or fleet profile ``profile``."""
        if variation is not None and profile is not None:
            raise ValueError("give a fleet profile or a variation, not both")
        chosen = variation if variation is not None else fleet_profile(profile).variation
        device = cls(qube_unit_params(fleet_seed, unit, chosen), config)
        device.name = f"QUBE unit {unit} of fleet seed {fleet_seed}"
        return device

    @property
    def state(self) -> np.ndarray:
        """A copy of the true state [theta, alpha, theta_dot, alpha_dot] (the agent never sees this)."""
        return self._state.copy()

    @property
    def readings(self) -> tuple[float, float]:
        """The encoder readings (arm, pendulum), pendulum unwrapped, offsets included (rad)."""
        return float(self._sensor[S_THETA]), float(self._sensor[S_ALPHA])

    @property
    def applied_volts(self) -> float:
        """The voltage that acted during the last period."""
        return float(self._sensor[S_APPLIED])

    def set_state(self, state: np.ndarray) -> np.ndarray:
        """Place the unit at ``state``, sensors at rest (velocities 0, 0 V held); return the observation."""
        self._state[:] = np.asarray(state, dtype=np.float64)
        sense_at_rest(self._state, self._coefficients, self._sensor, self.config.quantise)
        write_observation(self._sensor, self._obs)
        return self._obs

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Device-side reset like the rig: from a (seeded) hanging start, swing up, catch, settle; where the
        swing-up has not settled within ``config.reset_timeout`` the pendulum is put upright by hand (at
        rest, arm centred) and settled. Returns the first observation (a buffer the device reuses).
        Raises DeviceResetError if that has not settled within :data:`HAND_SETTLE_SECONDS` either."""
        rng = np.random.default_rng(seed)
        angle, rate = RESET_PERTURBATION
        self.set_state(np.array([0.0, math.pi + rng.uniform(-angle, angle), 0.0, rng.uniform(-rate, rate)]))
        periods, travel = self._settle(self.config.reset_timeout)
        self.last_reset_by_hand = periods < 0
        self.last_unsettled = unsettled_reason(self._state) if self.last_reset_by_hand else ""
        tried = 0
        if self.last_reset_by_hand:
            if not self.hand_resets:
                log.warning(
                    "%s: the swing-up did not settle within %s s (%s), so the pendulum is put upright by "
                    "hand (said once per unit; hand_resets counts them)",
                    self.name, self.config.reset_timeout, self.last_unsettled,
                )  # fmt: skip
            self.hand_resets += 1
            tried = math.ceil(self.config.reset_timeout / self.config.device_period)
            self.set_state(np.zeros(4))  # upright, at rest, arm centred
            periods, travel = self._settle(HAND_SETTLE_SECONDS)
        if periods < 0:
            raise DeviceResetError(
                f"swing-up did not settle within {self.config.reset_timeout} s, nor the pendulum put upright "
                f"by hand within {HAND_SETTLE_SECONDS} s (parameters {self.params}); check the damping range"
            )
        self.last_reset_seconds = (tried + periods) * self.config.device_period
        self.last_reset_arm_travel = travel
        write_observation(self._sensor, self._obs)
        return self._obs

    @property
    def last_reset_rig_seconds(self) -> float:
        """What the last reset took on a rig: its device time, plus a person's if one ended it."""
        return self.last_reset_seconds + (HAND_RESET_SECONDS if self.last_reset_by_hand else 0.0)

    def _settle(self, seconds: float) -> tuple[int, float]:
        """The reset's controllers for at most ``seconds``: periods used (−1: not settled), arm travel."""
        period = self.config.device_period
        return device_reset(
            self._state,
            self._coefficients,
            self._sensor,
            self._device_settings,
            self._controllers,
            math.ceil(seconds / period),
            max(1, round(SETTLE_SECONDS / period)),
        )

    def step_volts(self, volts: float) -> np.ndarray:
        """One control period with ``volts`` commanded; returns the observation buffer."""
        agent_step(self._state, self._coefficients, self._sensor, self._agent_settings, volts, self._obs)
        return self._obs

    def step(self, action: int) -> np.ndarray:
        """One control period with action index 0, 1 or 2 (power −60, 0, +60); returns the observation."""
        if not 0 <= action <= 2:
            raise ValueError(f"action {action!r} is out of range (choose 0, 1 or 2: power -60, 0, +60)")
        return self.step_volts(ACTION_VOLTS[action])

    def balance(self, n_periods: int) -> float:
        """Run Quanser's balance law at the agent's control period; return the largest |alpha| reading."""
        x, c, settings = self._state, self._coefficients, self._agent_settings
        return float(run_balance(x, c, self._sensor, settings, self._controllers, n_periods))

    def close(self) -> None:
        """Nothing to release for a simulated unit."""


class QubeVoltageUnit:
    """A QUBE unit commanded by a vector ``[volts]`` (a continuous action) instead of an action index."""

    def __init__(self, device: QubeDevice) -> None:
        self.device = device

    def reset(self, seed: int | None = None) -> np.ndarray:
        """The device-side reset of :meth:`QubeDevice.reset`."""
        return self.device.reset(seed)

    def step(self, action: np.ndarray) -> np.ndarray:
        """One control period with ``action[0]`` volts commanded; returns the observation buffer."""
        return self.device.step_volts(float(action[0]))

    def close(self) -> None:
        """Close the unit."""
        self.device.close()


def unsettled_reason(state: np.ndarray) -> str:
    """Why a swing-up that ran out of time stands where it does (``state``: [theta, alpha, ...], alpha from
    upright): ``held up, not settled`` (the balance law holds it, but outside the settle windows: an arm held
    off centre by cable torque or dead zone) or ``never caught``."""
    alpha = abs(math.remainder(float(state[1]), 2.0 * math.pi))
    if alpha < math.radians(CATCH_DEGREES):
        return f"held up, not settled: arm at {math.degrees(float(state[0])):+.0f}°"
    return "never caught"


_VOLTS = np.array(ACTION_VOLTS, dtype=np.float64)  # volts of action index 0, 1, 2


@njit(cache=True)
def _step_rows(
    states: np.ndarray,
    coefficients: np.ndarray,
    sensors: np.ndarray,
    settings: np.ndarray,
    rows: np.ndarray,
    volts: np.ndarray,
    obs: np.ndarray,
) -> None:  # pragma: no cover - compiled (each row is QubeDevice.step's own call; the tests compare both)
    for j in range(rows.shape[0]):
        i = rows[j]
        agent_step(states[i], coefficients[i], sensors[i], settings[i], volts[j], obs[j])


class QubeBatch:
    """The devices ``devices`` stepped together, row i ``devices[i]``, each state held while it steps."""

    def __init__(self, devices: Sequence[QubeDevice]) -> None:
        if not devices:
            raise ValueError("a batch of QUBE units needs at least one unit")
        self.devices = list(devices)
        self._coefficients = np.array([d._coefficients for d in self.devices], dtype=np.float64)
        self._settings = np.array([d._agent_settings for d in self.devices], dtype=np.float64)
        self._state = np.array([d._state for d in self.devices], dtype=np.float64)
        self._sensor = np.array([d._sensor for d in self.devices], dtype=np.float64)

    def load(self, row: int) -> None:
        """Take unit ``row``'s state and sensor pipeline from its device."""
        device = self.devices[row]
        self._state[row] = device._state
        self._sensor[row] = device._sensor

    def store(self, row: int) -> None:
        """Hand unit ``row``'s state and sensor pipeline back to its device."""
        device = self.devices[row]
        device._state[:] = self._state[row]
        device._sensor[:] = self._sensor[row]

    def state(self, row: int) -> np.ndarray:
        """A copy of unit ``row``'s true state as the batch holds it (float64)."""
        return self._state[row].copy()

    def sensor(self, row: int) -> np.ndarray:
        """A copy of unit ``row``'s sensor pipeline as the batch holds it (float64)."""
        return self._sensor[row].copy()

    def step(self, rows: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """One control period for the units ``rows`` with action indices ``actions``: their observations."""
        indices = np.asarray(actions, dtype=np.int64)
        if indices.size and not bool(np.all((indices >= 0) & (indices <= 2))):
            bad = int(indices[(indices < 0) | (indices > 2)][0])
            raise ValueError(f"action {bad!r} is out of range (choose 0, 1 or 2: power -60, 0, +60)")
        obs = np.empty((len(rows), 4), dtype=np.float32)
        _step_rows(
            self._state,
            self._coefficients,
            self._sensor,
            self._settings,
            np.asarray(rows, dtype=np.int64),
            _VOLTS[indices],
            obs,
        )
        return obs
