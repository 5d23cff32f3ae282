"""``fleetrl device``: serve one unit over MQTT through a device bridge (the Raspberry Pi's role), and the
driver options it shares with ``fleetrl control``."""

from __future__ import annotations

import argparse
import signal
from typing import TYPE_CHECKING, Any

from fleetrl.cli.settings_args import add_broker_arguments, add_connect_timeout, add_fleet_profile_argument
from fleetrl.envs.unit_factory import DRIVER_FORM, is_factory_reference, load_driver_function
from fleetrl.link.realtime import request_realtime_priority
from fleetrl.runs.settings import BrokerLogin

if TYPE_CHECKING:  # the driver modules load numba: only when the command runs
    from fleetrl.link.driver import DeviceDriver

DRIVERS = ("sim", "qube-spi")


def register(subparsers: Any) -> None:
    """Add the ``device`` subcommand to ``subparsers`` (the result of ``add_subparsers``)."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "device", help="serve one unit (simulated, or a QUBE on SPI) over MQTT through a device bridge"
    )
    add_broker_arguments(p, "default: an embedded broker")
    p.add_argument("--run-id", default="default", help="run whose device topics to serve (default: default)")
    p.add_argument("--unit", type=int, required=True, help="index of the unit in the fleet")
    p.add_argument(
        "--env",
        default=None,
        choices=("qube", "cartpole"),
        help="--driver sim: the built-in unit type (default qube; a qube bridge serves the discrete and the "
        "continuous QUBE task)",
    )
    add_driver_arguments(p)
    add_connect_timeout(p)
    p.set_defaults(handler=cmd_device)


def add_driver_arguments(p: argparse.ArgumentParser) -> None:
    """The options that choose and configure a unit's driver and its safety."""
    p.add_argument("--fleet-seed", type=int, default=0, help="seed of the fleet's per-unit dynamics")
    add_fleet_profile_argument(p)
    p.add_argument("--realtime", action="store_true", help="fixed control period, last command held")
    p.add_argument(
        "--driver",
        default="sim",
        metavar="{sim,qube-spi,PKG.MOD:FUNCTION}",
        help="sim: a simulated unit of the fleet (default); qube-spi: a QUBE-Servo 2 on the Raspberry Pi's "
        "SPI bus (implies --realtime; pip install 'fleetrl[pi]'); PKG.MOD:FUNCTION: your own unit type's "
        "driver(unit, fleet_seed, *, realtime) -> DeviceDriver",
    )
    p.add_argument("--spi-bus", type=int, default=0, help="qube-spi: SPI bus number (default 0)")
    p.add_argument("--spi-device", type=int, default=0, help="qube-spi: chip select (default 0: spidev0.0)")
    p.add_argument(
        "--spi-device-id",
        default=None,
        help="qube-spi: the device id every reply must carry (e.g. 0x0309; default: the first reply's)",
    )
    p.add_argument(
        "--period-ms", type=float, default=None, help="control period in ms (qube only; default 6)"
    )
    p.add_argument(
        "--watchdog-ms", type=float, default=100.0, help="motor off after this long without a command"
    )
    p.add_argument(
        "--rt-priority",
        type=int,
        default=10,
        help="with --realtime: SCHED_FIFO priority of the bridge process (needs root/CAP_SYS_NICE; 0: none)",
    )


def cmd_device(args: argparse.Namespace) -> int:
    """Run the bridge (on an embedded broker without ``--broker``) until Ctrl-C or SIGTERM; the motor is off
    and ``offline`` announced when it returns."""
    from fleetrl.link.bridge import DeviceBridge
    from fleetrl.transport.broker import EmbeddedBroker
    from fleetrl.transport.mqtt import MqttTransport

    login = BrokerLogin(broker=args.broker, broker_password_file=args.broker_password_file)
    login.validate_broker()  # before the driver or a broker starts
    realtime = realtime_mode(args)
    driver = make_driver(args, realtime)
    broker = None
    bridge = None
    try:
        url = args.broker
        if url is None:
            broker = EmbeddedBroker().start()
            url = broker.url
            print(f"broker: {url}", flush=True)
        bridge = DeviceBridge(
            MqttTransport(url, connect_timeout=args.connect_timeout, password=login.broker_password),
            driver,
            args.run_id,
            args.unit,
            realtime=realtime,
            watchdog=args.watchdog_ms / 1e3,
        )
        signal.signal(signal.SIGTERM, lambda *_: bridge.stop() if bridge else None)  # motor off, offline
        bridge.serve()
    finally:
        if bridge is not None:
            bridge.close()  # closes the driver too
        else:
            driver.close()
        if broker is not None:
            broker.close()
    return 0


def realtime_mode(args: argparse.Namespace) -> bool:
    """Whether the unit runs in real time (on hardware always: time runs whether a command came or not);
    then at ``--rt-priority``."""
    realtime = args.realtime or args.driver == "qube-spi"
    if realtime and args.rt_priority > 0:
        request_realtime_priority(args.rt_priority)
    return realtime


def make_driver(args: argparse.Namespace, realtime: bool) -> DeviceDriver:
    """The driver the arguments choose; ValueError (exit 2) for a bad combination, ``QubeFault`` (exit 1)
    when the QUBE cannot be reached or answers wrongly."""
    from fleetrl.link.driver import simulated_driver

    period = None if args.period_ms is None else args.period_ms / 1e3
    if args.driver not in DRIVERS:
        return user_driver(args, realtime)
    env = args.env or "qube"
    if args.driver == "sim":
        return simulated_driver(
            env,
            args.unit,
            args.fleet_seed,
            fleet_profile=args.fleet_profile,
            period=period,
            realtime=realtime,
        )
    from fleetrl.link.qube_spi import QubeSpiDriver

    if env != "qube":
        raise ValueError(f"--driver qube-spi drives a qube unit, not {env!r} (use --env qube)")
    if args.spi_bus < 0 or args.spi_device < 0:
        raise ValueError(f"--spi-bus and --spi-device must be >= 0, got {args.spi_bus} and {args.spi_device}")
    if period is not None and not period > 0:
        raise ValueError(f"--period-ms must be positive, got {args.period_ms}")
    return QubeSpiDriver(
        args.spi_bus,
        args.spi_device,
        control_period=0.006 if period is None else period,
        expected_id=None if args.spi_device_id is None else device_id(args.spi_device_id),
    )


def user_driver(args: argparse.Namespace, realtime: bool) -> DeviceDriver:
    """The driver a user's ``--driver package.module:function`` returns for ``--unit`` of ``--fleet-seed``;
    ValueError (exit 2) for a bad reference or result, or options of the built-in units."""
    from fleetrl.link.driver import driver_of

    if not is_factory_reference(args.driver):
        raise ValueError(f"--driver {args.driver!r}: choose sim, qube-spi or your own as {DRIVER_FORM}")
    given = [flag for flag, value in [("--env", args.env), ("--fleet-profile", args.fleet_profile),
                                      ("--period-ms", args.period_ms)] if value is not None]  # fmt: skip
    if given:
        what = f"{', '.join(given)} configure built-in simulated units"
        raise ValueError(f"{what}; driver {args.driver!r} builds its own unit")
    return driver_of(load_driver_function(args.driver), args.unit, args.fleet_seed, realtime=realtime)


def device_id(text: str) -> int:
    """A 16-bit device id from decimal or 0x-hex text; ValueError otherwise."""
    try:
        value = int(text, 0)
    except ValueError:
        raise ValueError(f"--spi-device-id {text!r} is not a number (e.g. 0x0309 or 777)") from None
    if not 0 < value < 0xFFFF:
        raise ValueError(f"--spi-device-id {text!r} is not a 16-bit id (0x0001 to 0xFFFE)")
    return value
