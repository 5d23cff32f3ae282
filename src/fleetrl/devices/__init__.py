"""Device physics: QUBE-Servo 2 and CartPole units with per-unit deviations (knows nothing of RL or MQTT)."""
