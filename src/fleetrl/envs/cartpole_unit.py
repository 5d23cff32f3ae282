"""``fleetrl/CartPoleUnit-v0``: CartPole-v1 (observation, actions, reward, termination) on one unit of a fleet
whose units differ by up to ±10 % (the ``standard`` fleet profile; ``wide``: ±40 %)."""

import math

import gymnasium
import numpy as np

from fleetrl.devices.cartpole import THETA_LIMIT, X_LIMIT, CartPoleDevice
from fleetrl.devices.variation import check_unit
from fleetrl.envs.link_env import CART, FRAME, PENDULUM, TRACK, LinkEnv, blank, line
from fleetrl.link.base import DeviceLink
from fleetrl.link.inprocess import InProcessLink


class CartPoleUnitEnv(LinkEnv):
    """CartPole-v1 on unit ``unit`` of fleet ``fleet_seed``, simulated in-process or reached by ``link``."""

    def __init__(
        self,
        unit: int = 0,
        fleet_seed: int = 0,
        *,
        fleet_profile: str | None = None,
        link: DeviceLink | None = None,
        render_mode: str | None = None,
    ) -> None:
        self.unit, self.fleet_seed = check_unit(unit, fleet_seed)
        if link is not None and fleet_profile is not None:
            raise ValueError("options ['fleet_profile'] configure the in-process simulation; not with link=")
        device_link = link or InProcessLink(
            CartPoleDevice.from_fleet(self.unit, self.fleet_seed, profile=fleet_profile)
        )
        super().__init__(device_link, 2, render_mode=render_mode)
        big = np.finfo(np.float32).max  # CartPole-v1's bounds
        high = np.array([X_LIMIT * 2, big, THETA_LIMIT * 2, big], dtype=np.float32)
        self.observation_space = gymnasium.spaces.Box(-high, high, dtype=np.float32)
        self.action_space = gymnasium.spaces.Discrete(2)

    def judge(self, obs: np.ndarray) -> tuple[float, bool]:
        """CartPole-v1: +1 every step; terminate when the cart or the pole leaves its band."""
        return 1.0, not (abs(float(obs[0])) <= X_LIMIT and abs(float(obs[2])) <= THETA_LIMIT)

    @staticmethod
    def judge_rows(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`judge` for every row of ``obs`` (n, 4), compared in float64 as :meth:`judge` does."""
        x = np.abs(obs[:, 0].astype(np.float64))
        theta = np.abs(obs[:, 2].astype(np.float64))
        return np.ones(obs.shape[0]), ~((x <= X_LIMIT) & (theta <= THETA_LIMIT))

    def frame(self, obs: np.ndarray) -> np.ndarray:
        """The cart on its track (±2.4 m across the frame) and the pole (θ, 0 = upright)."""
        x, theta = float(obs[0]), float(obs[2])
        img = blank()
        track_y, scale = FRAME * 0.75, FRAME / 5.6
        line(img, (0, track_y), (FRAME - 1, track_y), TRACK, 1)
        cart_x = FRAME / 2 + x * scale
        line(img, (cart_x - 12, track_y - 5), (cart_x + 12, track_y - 5), CART, 9)
        length = FRAME * 0.4
        pole_y = track_y - 10
        tip = (cart_x + length * math.sin(theta), pole_y - length * math.cos(theta))
        line(img, (cart_x, pole_y), tip, PENDULUM, 5)
        return img
