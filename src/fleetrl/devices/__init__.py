"""Device physics, knowing nothing of RL or MQTT: QUBE-Servo 2 units (``qube``) and CartPole units
(``cartpole``, many stepped together in ``cartpole_batch``), their per-unit deviations and fleet profiles
(``variation``), a unit built by name (``factory``), and the paper's homogeneity test (``homogeneity``)."""
