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
    for env_id, entry_point, cap in (
        (QUBE_BALANCE_ID, "fleetrl.envs.qube_balance:QubeBalanceEnv", QUBE_EPISODE_CAP),
        (QUBE_BALANCE_CONTINUOUS_ID, "fleetrl.envs.qube_balance:QubeBalanceContinuousEnv", QUBE_EPISODE_CAP),
        (CARTPOLE_UNIT_ID, "fleetrl.envs.cartpole_unit:CartPoleUnitEnv", CARTPOLE_EPISODE_CAP),
    ):
        if env_id not in registry:
            gymnasium.register(id=env_id, entry_point=entry_point, max_episode_steps=cap)
