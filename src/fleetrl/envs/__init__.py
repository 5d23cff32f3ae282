"""Cyber environments: Gymnasium envs over a device link (``link_env``) with the paper's reward and episode
cap: ``qube_balance`` (both QUBE tasks) and ``cartpole_unit`` (registered in ``registration``), a user's unit
type (``unit_factory``), the catalogue of unit types and their device side (``catalog``),
wrappers of a unit's env (``wrappers``: last step, paced, stalled) and a unit host's envs (``host_envs``)."""
