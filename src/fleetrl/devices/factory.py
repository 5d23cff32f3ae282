"""Build a simulated unit of either device type by name."""

from fleetrl.devices.cartpole import CartPoleDevice
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.devices.qube.params import qube_config
from fleetrl.devices.variation import check_unit

DEVICE_TYPES = ("qube", "cartpole")  # the unit types a fleet can be made of


def make_device(
    unit_type: str,
    unit: int = 0,
    fleet_seed: int = 0,
    *,
    fleet_profile: str | None = None,
    **config: object,
) -> QubeDevice | CartPoleDevice:
    """Unit ``unit`` of fleet ``fleet_seed`` of type ``qube`` or ``cartpole``, drawn with ``fleet_profile``
    (None: its default); ``config`` holds ``QubeConfig`` fields for a QUBE (a CartPole takes none)."""
    unit, fleet_seed = check_unit(unit, fleet_seed)
    if unit_type == "qube":
        return QubeDevice.from_fleet(unit, fleet_seed, qube_config(**config), profile=fleet_profile)
    if unit_type == "cartpole":
        if config:
            raise ValueError(f"a cartpole unit takes no options, got {sorted(config)}")
        return CartPoleDevice.from_fleet(unit, fleet_seed, profile=fleet_profile)
    raise ValueError(f"unknown unit type {unit_type!r} (choose {' or '.join(DEVICE_TYPES)})")
