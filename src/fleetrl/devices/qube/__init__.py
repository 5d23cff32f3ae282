"""The QUBE-Servo 2 rotary inverted pendulum: parameters, compiled physics, controllers, the unit."""

from fleetrl.devices.qube.device import ACTION_VOLTS, DeviceResetError, QubeDevice
from fleetrl.devices.qube.params import NOMINAL, QubeConfig, QubeParams

__all__ = ["ACTION_VOLTS", "NOMINAL", "DeviceResetError", "QubeConfig", "QubeDevice", "QubeParams"]
