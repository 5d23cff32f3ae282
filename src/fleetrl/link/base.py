"""The one way an environment reaches its device: reset, step, close. A link is in-process
(``InProcessLink``) or an MQTT bridge to a device process; observations are float32 arrays the link may
reuse: copy one to keep it."""

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, Protocol, runtime_checkable

import numpy as np

NO_INFO: Mapping[str, float] = MappingProxyType({})
"""the (read-only, shared) info of a step that has nothing to report"""

Action = Any
"""a discrete action index (int), or a command vector (float32 ndarray, e.g. ``[volts]``) for a continuous
task; each device declares which it takes"""


@runtime_checkable
class Device(Protocol):
    """What the in-process link needs of a simulated unit (QubeDevice, CartPoleDevice): a seeded reset
    returning the first observation, a step of one control period returning the observation, close."""

    def reset(self, seed: int | None = None) -> np.ndarray: ...
    def step(self, action: Action) -> np.ndarray: ...
    def close(self) -> None: ...


@runtime_checkable
class DeviceLink(Protocol):
    """How an env talks to its device: a seeded device-side reset (for a QUBE: swing-up and settle)
    returning the first observation; a step returning the next observation and small numeric extras."""

    def reset(self, seed: int | None = None) -> np.ndarray: ...
    def step(self, action: Action) -> tuple[np.ndarray, Mapping[str, float]]: ...
    def close(self) -> None: ...
