"""The device side of a unit type behind device bridges: which driver a bridge serves and whether it fits
the env. Apart from :mod:`fleetrl.envs.catalog` because the drivers load the simulated devices (numba)."""

from __future__ import annotations

from fleetrl.envs.catalog import EnvSpec, UnitDescription, check_takes_link
from fleetrl.envs.unit_factory import DRIVER_FORM, load_driver_function
from fleetrl.link.driver import DriverFunction, DriverSpec, driver_of


def bridge_driver(env: EnvSpec, device_driver: str | None) -> str | DriverFunction:
    """What the bridges of ``env``'s units serve: a user's driver function, else the built-in's device."""
    check_takes_link(env)
    if device_driver is not None:
        function: DriverFunction = load_driver_function(device_driver)
        return function
    if env.device is None:
        raise ValueError(
            f"{env.title} needs --device-driver {DRIVER_FORM} for its device bridges: the function "
            "driver(unit, fleet_seed, *, realtime) -> DeviceDriver that serves one unit"
        )
    return env.device


def check_driver_fits(spec: DriverSpec, unit: UnitDescription, where: str) -> None:
    """A ValueError naming ``where`` if a driver of ``spec`` cannot serve an env described by ``unit``."""
    if spec.sensor_size != unit.sensor_dim:
        size = unit.sensor_size
        reads = f"observes {unit.obs_dim}" if size is None else f"reads {size} (its sensor_size)"
        raise ValueError(f"{where} declares {spec.sensor_size} sensor values; the env {reads}")
    action = unit.action
    if action.kind == "discrete" and spec.n_actions != action.n:
        raise ValueError(f"{where} declares {spec.n_actions} discrete commands; the env has {action} actions")
    if action.kind == "box" and (spec.command_size,) != action.shape:
        raise ValueError(
            f"{where} takes a command vector of {spec.command_size}; the env's actions are Box{action.shape}"
        )


def check_bridge_driver(driver: str | DriverFunction, unit: UnitDescription, fleet_seed: int = 0) -> None:
    """Build unit 0's driver of a user's ``driver`` function, check it fits ``unit`` and close it."""
    if isinstance(driver, str):
        return
    served = driver_of(driver, 0, fleet_seed, realtime=False)
    try:
        check_driver_fits(served.spec, unit, f"device driver {served.spec.kind!r} (unit 0)")
    finally:
        served.close()
