"""``fleetrl device``: serve one simulated unit over MQTT through a device bridge (the Raspberry Pi's role).

Registered on the main parser by ``register(subparsers)``. Without ``--broker`` an embedded broker is
started and its URL printed (the one line this command prints).
"""

from __future__ import annotations

import argparse
import signal
from typing import Any


def register(subparsers: Any) -> None:
    """Add the ``device`` subcommand to ``subparsers`` (the result of ``add_subparsers``)."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "device", help="serve one simulated unit over MQTT (device bridge: lockstep or real time)"
    )
    from fleetrl.cli.settings_args import (
        add_broker_arguments,
        add_connect_timeout,
        add_fleet_profile_argument,
    )

    add_broker_arguments(p, "default: an embedded broker")
    p.add_argument("--run-id", default="default", help="run whose device topics to serve (default: default)")
    p.add_argument("--unit", type=int, required=True, help="index of the unit in the fleet")
    p.add_argument("--env", default="qube", choices=("qube", "cartpole"), help="unit type (default qube)")
    p.add_argument("--fleet-seed", type=int, default=0, help="seed of the fleet's per-unit dynamics")
    add_fleet_profile_argument(p)
    p.add_argument("--realtime", action="store_true", help="fixed control period, last command held")
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
    add_connect_timeout(p)
    p.set_defaults(handler=cmd_device)


def cmd_device(args: argparse.Namespace) -> int:
    """Run the bridge until interrupted (Ctrl-C or SIGTERM); the motor is off and ``offline`` announced
    when it returns."""
    from fleetrl.link.bridge import DeviceBridge, request_realtime_priority
    from fleetrl.link.driver import simulated_driver
    from fleetrl.runs.settings import BrokerLogin
    from fleetrl.transport.broker import EmbeddedBroker
    from fleetrl.transport.mqtt import MqttTransport

    login = BrokerLogin(broker=args.broker, broker_password_file=args.broker_password_file)
    login.validate_broker()  # before the driver or a broker starts
    if args.realtime and args.rt_priority > 0:
        request_realtime_priority(args.rt_priority)
    period = None if args.period_ms is None else args.period_ms / 1e3
    driver = simulated_driver(
        args.env,
        args.unit,
        args.fleet_seed,
        fleet_profile=args.fleet_profile,
        period=period,
        realtime=args.realtime,
    )
    broker = None
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
        realtime=args.realtime,
        watchdog=args.watchdog_ms / 1e3,
    )
    signal.signal(signal.SIGTERM, lambda *_: bridge.stop())  # a service manager's stop: motor off, offline
    try:
        bridge.serve()
    finally:
        bridge.close()
        if broker is not None:
            broker.close()
    return 0
