"""``fleetrl/QubeBalance-v0``: balance an (already swung-up) QUBE-Servo 2 pendulum, as in the paper, and
``fleetrl/QubeBalanceContinuous-v0``, the same task with the motor voltage as a continuous action.
Observation: pendulum angle (0 upright) and velocity, motor angle and velocity, as the encoders read them."""

import math

import gymnasium
import numpy as np

from fleetrl.devices.qube.device import QubeDevice, QubeVoltageUnit
from fleetrl.devices.qube.params import qube_config
from fleetrl.devices.variation import check_unit
from fleetrl.envs.link_env import ARM, FRAME, PENDULUM, TRACK, LinkEnv, blank, box_action, line
from fleetrl.link.base import DeviceLink
from fleetrl.link.inprocess import InProcessLink

PENDULUM_LIMIT = math.radians(7.5)  # the paper's success band on the pendulum angle
ARM_LIMIT = math.pi / 2.0  # the rig's arm protection limit
VELOCITY_BOUND = 500.0  # observation bound on the velocities (rad/s); the arm's no-load speed is ~240 rad/s
ACTION_VOLTS = 3.0  # the continuous task's action bound (V): about twice the discrete task's ±1.44 V


class QubeBalanceEnv(LinkEnv):
    """Balance unit ``unit`` of fleet ``fleet_seed`` (``fleet_profile`` None: ``table2``), simulated
    in-process (``options``: ``QubeConfig`` fields) or reached through ``link``; ``render_mode`` None or
    ``rgb_array``. Actions 0, 1, 2: motor power −60, 0, +60 (≈ −1.44, 0, +1.44 V)."""

    index_actions = 3  # how many action indices the env takes (0: none, a continuous task)

    def __init__(
        self,
        unit: int = 0,
        fleet_seed: int = 0,
        *,
        fleet_profile: str | None = None,
        link: DeviceLink | None = None,
        render_mode: str | None = None,
        **options: object,
    ) -> None:
        self.unit, self.fleet_seed = check_unit(unit, fleet_seed)
        if link is None:
            device = QubeDevice.from_fleet(
                self.unit, self.fleet_seed, qube_config(**options), profile=fleet_profile
            )
            link = self.in_process_link(device)
        elif options or fleet_profile is not None:
            given = sorted(options) + (["fleet_profile"] if fleet_profile is not None else [])
            raise ValueError(f"options {given} configure the in-process simulation; not with link=")
        super().__init__(link, n_actions=self.index_actions, render_mode=render_mode)
        high = np.array([math.pi, VELOCITY_BOUND, 2.0 * math.pi, VELOCITY_BOUND], dtype=np.float32)
        self.observation_space = gymnasium.spaces.Box(-high, high, dtype=np.float32)
        self.action_space = gymnasium.spaces.Discrete(3)

    def in_process_link(self, device: QubeDevice) -> DeviceLink:
        """The link to a simulated unit: its action indices straight to the device."""
        return InProcessLink(device)

    def judge(self, obs: np.ndarray) -> tuple[float, bool]:
        """+1 while the pendulum is within 7.5° and the arm within ±π/2; otherwise 0 and terminate."""
        if abs(float(obs[0])) <= PENDULUM_LIMIT and abs(float(obs[2])) <= ARM_LIMIT:
            return 1.0, False
        return 0.0, True

    @staticmethod
    def judge_rows(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`judge` for every row of ``obs`` (n, 4), compared in float64 as :meth:`judge` does."""
        alpha = np.abs(obs[:, 0].astype(np.float64))
        theta = np.abs(obs[:, 2].astype(np.float64))
        held = (alpha <= PENDULUM_LIMIT) & (theta <= ARM_LIMIT)
        return held.astype(np.float64), ~held

    def frame(self, obs: np.ndarray) -> np.ndarray:
        """Left: the arm seen from above (θ); right: the pendulum seen from the front (α, 0 = upright)."""
        alpha, theta = float(obs[0]), float(obs[2])
        img = blank()
        cx, cy, r = FRAME * 0.25, FRAME * 0.5, FRAME * 0.2
        line(img, (cx, cy), (cx + r * math.sin(theta), cy - r * math.cos(theta)), ARM, 5)
        px, py, length = FRAME * 0.75, FRAME * 0.75, FRAME * 0.5
        line(img, (px - 25, py), (px + 25, py), TRACK, 3)
        line(img, (px, py), (px + length * math.sin(alpha), py - length * math.cos(alpha)), PENDULUM, 5)
        return img


class QubeBalanceContinuousEnv(QubeBalanceEnv):
    """Balance one QUBE unit commanding the motor voltage, ``[volts]`` within ±``action_volts``."""

    index_actions = 0

    def __init__(
        self,
        unit: int = 0,
        fleet_seed: int = 0,
        *,
        fleet_profile: str | None = None,
        link: DeviceLink | None = None,
        render_mode: str | None = None,
        action_volts: float = ACTION_VOLTS,
        **options: object,
    ) -> None:
        max_volts = qube_config(**options).max_volts
        if not (isinstance(action_volts, int | float) and 0.0 < action_volts <= max_volts):
            raise ValueError(
                f"action_volts must be a number in (0, {max_volts}] (the amplifier's range), "
                f"got {action_volts!r}"
            )
        super().__init__(
            unit, fleet_seed, fleet_profile=fleet_profile, link=link, render_mode=render_mode, **options
        )
        bound = np.array([action_volts], dtype=np.float32)
        self.action_space = gymnasium.spaces.Box(-bound, bound, dtype=np.float32)

    def in_process_link(self, device: QubeDevice) -> DeviceLink:
        """The link to a simulated unit commanded in volts."""
        return InProcessLink(QubeVoltageUnit(device))

    def link_action(self, action: object) -> np.ndarray:
        """``[volts]`` as float32, clipped to the box; ValueError for another shape or a non-finite value."""
        space = self.action_space
        assert isinstance(space, gymnasium.spaces.Box)
        return box_action(action, space)
