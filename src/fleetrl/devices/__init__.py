"""Device physics, knowing nothing of RL or MQTT: QUBE-Servo 2 units (``qube``) and CartPole units
(``cartpole``, many stepped together in ``cartpole_batch``, fleet profiles in ``cartpole_profiles``), their
per-unit deviations drawn from a seed (``variation``), a unit built by name (``factory``), and the paper's
homogeneity test (``homogeneity``; on CartPole units, ``cartpole_homogeneity``)."""
