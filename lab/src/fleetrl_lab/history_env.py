"""QUBE units whose observation holds their last observation and action, as ``--env
fleetrl_lab.history_env:qube_wide`` or ``qube_table2``: the runs that chose the product's ``last_step``
setting, made before it was one (the same observation: :class:`fleetrl.envs.wrappers.LastStep`)."""

from __future__ import annotations

import gymnasium

from fleetrl.envs.registration import QUBE_BALANCE_ID, register_envs
from fleetrl.envs.wrappers import LastStep


def qube_wide(unit: int, fleet_seed: int) -> gymnasium.Env:
    """QUBE unit ``unit`` of the ``wide`` fleet ``fleet_seed``, its observation with the last step."""
    return _qube(unit, fleet_seed, "wide")


def qube_table2(unit: int, fleet_seed: int) -> gymnasium.Env:
    """QUBE unit ``unit`` of the ``table2`` fleet ``fleet_seed`` (the default), with the last step."""
    return _qube(unit, fleet_seed, "table2")


def _qube(unit: int, fleet_seed: int, profile: str) -> gymnasium.Env:
    register_envs()
    return LastStep(gymnasium.make(QUBE_BALANCE_ID, unit=unit, fleet_seed=fleet_seed, fleet_profile=profile))
