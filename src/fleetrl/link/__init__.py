"""Reaching a device behind one interface (``base``): in-process (``inprocess``), or over MQTT (``mqtt``,
messages in ``wire``) through a device bridge (``bridge``) that drives a unit's ``DeviceDriver``
(``driver``: simulated, or the QUBE on SPI in ``qube_spi`` and ``qube_reset``), paced in real time
(``realtime``); ``fleet`` starts a bridge per simulated unit."""

from fleetrl.link.base import NO_INFO, Device, DeviceLink
from fleetrl.link.inprocess import InProcessLink

__all__ = ["NO_INFO", "Device", "DeviceLink", "InProcessLink"]
