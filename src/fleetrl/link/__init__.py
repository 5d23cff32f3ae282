"""Reaching a device: in-process, or over MQTT through a device bridge, behind one interface."""

from fleetrl.link.base import NO_INFO, Device, DeviceLink
from fleetrl.link.inprocess import InProcessLink

__all__ = ["NO_INFO", "Device", "DeviceLink", "InProcessLink"]
