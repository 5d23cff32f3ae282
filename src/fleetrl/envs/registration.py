"""Gymnasium registration of the fleetrl environments (entry points load lazily)."""

import gymnasium

QUBE_BALANCE_ID = "fleetrl/QubeBalance-v0"
QUBE_BALANCE_CONTINUOUS_ID = "fleetrl/QubeBalanceContinuous-v0"
CARTPOLE_UNIT_ID = "fleetrl/CartPoleUnit-v0"
QUBE_EPISODE_CAP = 2500
CARTPOLE_EPISODE_CAP = 500


def register_envs() -> None:
    """Register the environments once; calling again is harmless."""
    registry = gymnasium.envs.registration.registry
    if QUBE_BALANCE_ID not in registry:
        gymnasium.register(
            id=QUBE_BALANCE_ID,
            entry_point="fleetrl.envs.qube_balance:QubeBalanceEnv",
            max_episode_steps=QUBE_EPISODE_CAP,
        )
    if QUBE_BALANCE_CONTINUOUS_ID not in registry:  # the same units and cap, the voltage as the action
        gymnasium.register(
            id=QUBE_BALANCE_CONTINUOUS_ID,
            entry_point="fleetrl.envs.qube_balance:QubeBalanceContinuousEnv",
            max_episode_steps=QUBE_EPISODE_CAP,
        )
    if CARTPOLE_UNIT_ID not in registry:
        gymnasium.register(
            id=CARTPOLE_UNIT_ID,
            entry_point="fleetrl.envs.cartpole_unit:CartPoleUnitEnv",
            max_episode_steps=CARTPOLE_EPISODE_CAP,
        )
