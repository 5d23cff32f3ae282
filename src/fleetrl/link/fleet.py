"""One device bridge per unit as daemon threads, each with its own MQTT connection, for ``fleetrl train …
--device-link mqtt`` (``fleetrl device --unit K`` serves one per process instead)."""

from __future__ import annotations

from collections.abc import Iterable
from types import TracebackType

from fleetrl.link.bridge import WATCHDOG_SECONDS, DeviceBridge
from fleetrl.link.driver import DeviceDriver, DriverFunction, driver_of, simulated_driver
from fleetrl.transport.mqtt import MqttTransport


class BridgeFleet:
    """The running bridges of a fleet; :meth:`close` (or leaving ``with``) stops them all."""

    def __init__(self, bridges: list[DeviceBridge]) -> None:
        self.bridges = bridges

    def close(self) -> None:
        """Stop every bridge (motor off, ``offline`` announced, disconnected)."""
        for bridge in self.bridges:
            bridge.close()

    def __enter__(self) -> BridgeFleet:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def start_bridges(
    url: str,
    run_id: str,
    env: str | DriverFunction,
    units: Iterable[int],
    fleet_seed: int = 0,
    *,
    fleet_profile: str | None = None,
    realtime: bool = False,
    period: float | None = None,
    watchdog: float = WATCHDOG_SECONDS,
) -> BridgeFleet:
    """Serve each of ``units`` of fleet ``fleet_seed`` from a bridge thread on ``url``; returns once every
    bridge has announced ``online``.

    :param env: a built-in unit type's simulated units (``qube`` or ``cartpole``), or a user's driver
        function ``driver(unit, fleet_seed, *, realtime) -> DeviceDriver``
    :param period: control period in seconds (QUBE only; not with a driver function)
    """
    if callable(env) and (fleet_profile is not None or period is not None):
        raise ValueError(
            "fleet_profile and period configure the built-in simulated units, not a driver function"
        )
    bridges: list[DeviceBridge] = []
    try:
        for unit in units:
            driver: DeviceDriver
            if callable(env):
                driver = driver_of(env, unit, fleet_seed, realtime=realtime)
            else:
                driver = simulated_driver(
                    env, unit, fleet_seed, fleet_profile=fleet_profile, period=period, realtime=realtime
                )
            bridge = DeviceBridge(
                MqttTransport(url), driver, run_id, unit, realtime=realtime, watchdog=watchdog
            )
            bridges.append(bridge.start())
    except BaseException:
        BridgeFleet(bridges).close()
        raise
    return BridgeFleet(bridges)
