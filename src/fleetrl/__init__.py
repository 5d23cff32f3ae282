"""fleetrl: federated reinforcement learning of control policies for a fleet of IoT devices of one type.

Importing the package registers the Gymnasium environments ``fleetrl/QubeBalance-v0`` and
``fleetrl/CartPoleUnit-v0`` (their modules load lazily, on ``gymnasium.make``), after applying the portable
mode when ``FLEETRL_PORTABLE=1`` (:mod:`fleetrl.portable`).
"""

from fleetrl import portable

portable.apply()  # before anything imports numba or runs a torch operation

from fleetrl.envs.registration import register_envs  # noqa: E402

__version__ = "0.1.0"

register_envs()
