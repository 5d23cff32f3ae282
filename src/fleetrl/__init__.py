"""fleetrl: federated reinforcement learning of control policies for a fleet of IoT devices of one type.

Importing the package registers the Gymnasium environments ``fleetrl/QubeBalance-v0`` and
``fleetrl/CartPoleUnit-v0`` (their modules load lazily, on ``gymnasium.make``).
"""

from fleetrl.envs.registration import register_envs

__version__ = "0.1.0"

register_envs()
