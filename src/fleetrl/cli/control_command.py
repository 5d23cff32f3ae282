"""``fleetrl export`` (a model file's greedy policy as ONNX, checked) and ``fleetrl control`` (a saved policy
run on one unit through its driver, with the device bridge's safety; no torch, no broker).

Registered on the main parser by ``register(subparsers)``; the handlers import the work, which loads numba
(neither the parser nor ``fleetrl control`` loads torch: docs/on-device.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from fleetrl.cli.device_command import DRIVERS, add_driver_arguments, make_driver
from fleetrl.cli.settings_args import add_fleet_profile_argument
from fleetrl.envs.catalog import get_env_spec
from fleetrl.link.realtime import request_realtime_priority

DEFAULT_ENV = "qube"


def register(subparsers: Any) -> None:
    """Add the ``export`` and ``control`` subcommands to ``subparsers``."""
    export: argparse.ArgumentParser = subparsers.add_parser(
        "export", help="write a saved policy as ONNX (observation -> greedy action) and check it"
    )
    export.add_argument("model", type=Path, help="a models/worker-K.safetensors file")
    export.add_argument("--out", type=Path, required=True, help="the .onnx file to write")
    add_model_env_argument(export)
    export.add_argument(
        "--check", type=int, default=1000, help="observations the export is checked on (default 1000)"
    )
    export.add_argument("--unit", type=int, default=0, help="the simulated unit the check's states come from")
    export.add_argument("--fleet-seed", type=int, default=0)
    add_fleet_profile_argument(export)
    export.add_argument("--seed", type=int, default=0, help="seed of the check's observations")
    export.set_defaults(handler=cmd_export)

    control: argparse.ArgumentParser = subparsers.add_parser(
        "control", help="run a saved policy (model file or ONNX) on one unit through its driver; no broker"
    )
    control.add_argument("model", type=Path, help="a models/worker-K.safetensors file or an exported .onnx")
    add_model_env_argument(control)
    control.add_argument("--unit", type=int, default=0, help="index of the unit in the fleet (default 0)")
    control.add_argument("--episodes", type=int, default=10, help="episodes to play (default 10)")
    control.add_argument("--seed", type=int, default=0, help="episode k resets with seed SEED + k")
    add_driver_arguments(control)
    control.set_defaults(handler=cmd_control)


def add_model_env_argument(p: argparse.ArgumentParser) -> None:
    """``--env``: the task the policy was trained on (its observations, actions and reward)."""
    p.add_argument(
        "--env",
        default=None,
        metavar="ENV",
        help="the env the policy was trained on: qube, qube-continuous, cartpole or package.module:factory "
        "(default: the one an exported file records, else the run's config.json beside models/, else qube)",
    )


def run_env(model: Path) -> str | None:
    """The env of the run a model file belongs to (``RUN/models/worker-K.safetensors`` beside
    ``RUN/config.json``), or None when it is not in a run directory."""
    config = model.parent.parent / "config.json"
    if model.parent.name != "models" or not config.is_file():
        return None
    try:
        env = json.loads(config.read_text()).get("env")
    except (OSError, ValueError, AttributeError):
        return None
    return env if isinstance(env, str) else None


def cmd_export(args: argparse.Namespace) -> int:
    """Write the ONNX file, print the check's result; exit 1 if it failed (no file is left then)."""
    from fleetrl.control.export import export_policy

    env = args.env or run_env(args.model) or DEFAULT_ENV
    try:
        check = export_policy(
            args.model,
            args.out,
            env,
            observations=args.check,
            seed=args.seed,
            unit=args.unit,
            fleet_seed=args.fleet_seed,
            fleet_profile=args.fleet_profile,
        )
    except ImportError as err:
        hint = "pip install 'fleetrl[export]'"
        raise ValueError(f"the export needs onnx and onnxruntime ({err}): {hint}") from None
    print(check.describe())
    if not check.passed:
        print(f"fleetrl export: {args.out} not written: the exported graph disagrees with fleetrl's policy")
        return 1
    print(f"wrote {args.out} (env {env}; input 'observation', output 'action': docs/on-device.md)")
    return 0


def cmd_control(args: argparse.Namespace) -> int:
    """Run the episodes, printing each score as it ends and their mean; the motor is off when this returns
    (Ctrl-C and SIGTERM included)."""
    from fleetrl.control.controller import run_on_unit
    from fleetrl.control.policies import load_policy

    if args.episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {args.episodes}")
    if not args.watchdog_ms > 0:
        raise ValueError(f"--watchdog-ms must be positive, got {args.watchdog_ms}")
    policy = load_policy(args.model)
    env = args.env or policy.env or run_env(args.model) or DEFAULT_ENV
    spec = get_env_spec(env)
    if args.driver in DRIVERS and spec.device is None:
        raise ValueError(f"{spec.title} is your own unit type: give its driver as --driver PKG.MOD:FUNCTION")
    realtime = args.realtime or args.driver == "qube-spi"
    if realtime and args.rt_priority > 0:
        request_realtime_priority(args.rt_priority)
    device = spec.device if args.driver in DRIVERS else None  # which built-in unit --driver sim simulates
    driver = make_driver(argparse.Namespace(**{**vars(args), "env": device}), realtime)
    mode = "real time" if realtime else "lockstep"
    what = f"{args.model} on {env} ({args.driver}, {mode})"
    print(f"unit {args.unit}: {what}, {args.episodes} episodes", flush=True)

    def report(episode: int, score: float) -> None:
        print(f"episode {episode + 1}: score {score:g}", flush=True)

    scores = run_on_unit(
        policy,
        env,
        driver,
        args.episodes,
        seed=args.seed,
        unit=args.unit,
        fleet_seed=args.fleet_seed,
        realtime=realtime,
        watchdog=args.watchdog_ms / 1e3,
        report=report,
    )
    print(f"mean score {sum(scores) / len(scores):g} over {len(scores)} episodes", flush=True)
    return 0
