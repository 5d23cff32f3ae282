"""Cyber environments: Gymnasium envs over a device link (``link_env``) with the paper's reward and episode
cap: ``qube_balance``, ``qube_continuous``, ``cartpole_unit`` (registered in ``registration``), a user's
unit type (``unit_factory``), the catalogue of unit types (``catalog``, ``spaces``, ``device_side``), paced
(``paced``) and stalling (``stalled``) units, a unit host's envs (``host_envs``), frames (``render``)."""
