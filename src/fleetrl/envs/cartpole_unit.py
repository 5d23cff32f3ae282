"""``fleetrl/CartPoleUnit-v0``: CartPole-v1 on one unit of a fleet whose units differ by up to ±10 % (the
``standard`` fleet profile; ``wide``: ±40 %).

Observation, actions, reward (+1 every step, the terminating one included) and termination
(|x| > 2.4 or |theta| > 12°) are CartPole-v1's; the 500-step cap is gymnasium's TimeLimit from the
registration.
"""

import gymnasium
import numpy as np

from fleetrl.devices.cartpole import THETA_LIMIT, X_LIMIT, CartPoleDevice
from fleetrl.devices.variation import check_unit
from fleetrl.envs.link_env import LinkEnv
from fleetrl.envs.render import cartpole_frame
from fleetrl.link.base import DeviceLink
from fleetrl.link.inprocess import InProcessLink


class CartPoleUnitEnv(LinkEnv):
    """CartPole-v1 on unit ``unit`` of fleet ``fleet_seed``.

    :param unit: index of the unit in the fleet (non-negative)
    :param fleet_seed: seed of the fleet; (fleet_seed, unit) fixes the unit's parameters
    :param fleet_profile: the fleet profile the in-process unit is drawn with (``standard``, the default, or
        ``wide``; see ``fleetrl.devices.cartpole_profiles``)
    :param link: reach the device through this link instead of simulating it in-process
    :param render_mode: None, or ``rgb_array`` for :meth:`render` frames
    """

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
        """:meth:`judge` for every row of ``obs`` (n, 4): rewards (float64) and terminations (bool), each
        row's what :meth:`judge` says of it (compared in float64, as :meth:`judge` does)."""
        x = np.abs(obs[:, 0].astype(np.float64))
        theta = np.abs(obs[:, 2].astype(np.float64))
        return np.ones(obs.shape[0]), ~((x <= X_LIMIT) & (theta <= THETA_LIMIT))

    def frame(self, obs: np.ndarray) -> np.ndarray:
        """An RGB picture of the unit in state ``obs``."""
        return cartpole_frame(obs)
