"""The one way an environment reaches its device: reset, step, close.

A link may be in-process (``InProcessLink``) or, later, an MQTT bridge to a device process; the env cannot
tell them apart. Observations are float32 arrays the link may reuse: copy one to keep it.
"""

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, Protocol, runtime_checkable

import numpy as np

NO_INFO: Mapping[str, float] = MappingProxyType({})
"""the (read-only, shared) info of a step that has nothing to report"""

Action = Any
"""what a link or device step takes: a discrete action index (int) for the discrete tasks, or a command
vector (float32 ndarray, e.g. ``[volts]``) for a continuous one; each device declares which it takes"""


@runtime_checkable
class Device(Protocol):
    """What the in-process link needs of a simulated unit (QubeDevice, CartPoleDevice)."""

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Bring the unit to the start of an episode; return its first observation."""
        ...

    def step(self, action: Action) -> np.ndarray:
        """Apply ``action`` (an index, or a command vector) for one control period; return the observation."""
        ...

    def close(self) -> None:
        """Release whatever the unit holds."""
        ...


@runtime_checkable
class DeviceLink(Protocol):
    """How an env talks to its device."""

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Device-side reset (for a QUBE: swing-up and settle), seeded; returns the first observation."""
        ...

    def step(self, action: Action) -> tuple[np.ndarray, Mapping[str, float]]:
        """Send ``action`` (an index, or a command vector); return the next observation and small numeric
        extras."""
        ...

    def close(self) -> None:
        """Stop using the device."""
        ...
