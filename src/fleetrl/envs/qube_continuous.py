"""``fleetrl/QubeBalanceContinuous-v0``: the QUBE balance task with the motor voltage as a continuous action.

Everything but the action is ``fleetrl/QubeBalance-v0``'s; the action is ``[volts]`` in
``Box(-ACTION_VOLTS, +ACTION_VOLTS, (1,))``, clipped beyond it as the amplifier saturates (docs/devices.md,
"Environments").
"""

import gymnasium
import numpy as np

from fleetrl.devices.qube.device import QubeDevice, QubeVoltageUnit
from fleetrl.devices.qube.params import qube_config
from fleetrl.envs.link_env import box_action
from fleetrl.envs.qube_balance import QubeBalanceEnv
from fleetrl.link.base import DeviceLink
from fleetrl.link.inprocess import InProcessLink

ACTION_VOLTS = 3.0
"""the action box's bound (V): about twice the discrete task's ±1.44 V, well inside Quanser's ±10 V"""


class QubeBalanceContinuousEnv(QubeBalanceEnv):
    """Balance one QUBE unit of a seeded fleet, commanding the motor voltage directly.

    Takes the arguments of :class:`~fleetrl.envs.qube_balance.QubeBalanceEnv` and:

    :param action_volts: the bound of the action box (V), at most the amplifier's ``max_volts`` (10 V)
    :param link: reach the device through this link (each step sends ``[volts]``) instead of simulating it
        in-process
    """

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
