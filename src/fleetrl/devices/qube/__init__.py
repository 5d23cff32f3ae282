"""The QUBE-Servo 2 rotary inverted pendulum: parameters, per-unit variation and fleet profiles (``params``),
compiled physics (``dynamics``), reset and balance controllers (``controllers``), the unit and units stepped
together (``device``)."""
