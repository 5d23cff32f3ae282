"""A link to a device object living in the same process (the simulated fleet's default)."""

from collections.abc import Mapping

import numpy as np

from fleetrl.link.base import NO_INFO, Action, Device


class InProcessLink:
    """Wraps a device object; adds nothing on the hot path (one attribute lookup and a call)."""

    def __init__(self, device: Device) -> None:
        self.device = device
        self._step = device.step

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Reset the device with ``seed``; return its first observation."""
        return self.device.reset(seed)

    @property
    def last_reset_seconds(self) -> float:
        """What the device's last reset took on a rig (its ``last_reset_rig_seconds``; 0 if it has none)."""
        return float(getattr(self.device, "last_reset_rig_seconds", 0.0))

    def step(self, action: Action) -> tuple[np.ndarray, Mapping[str, float]]:
        """Step the device (no extras to report)."""
        return self._step(action), NO_INFO

    def close(self) -> None:
        self.device.close()
