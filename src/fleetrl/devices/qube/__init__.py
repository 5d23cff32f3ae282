"""The QUBE-Servo 2 rotary inverted pendulum: parameters (``params``), compiled physics (``dynamics``),
reset and balance controllers (``controllers``), per-unit variation (``units``, ``fleet_profiles``), the unit
(``device``) and units stepped together (``batch``)."""
