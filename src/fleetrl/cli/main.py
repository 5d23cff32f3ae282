"""``fleetrl``: train a simulated fleet, evaluate a policy, test the fleet's homogeneity, run roles."""

import argparse
import json
import logging
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from fleetrl.cli import control_command, device_command, roles
from fleetrl.cli.settings_args import (
    add_broker_arguments,
    add_fleet_profile_argument,
    add_learning_argument,
    add_settings_arguments,
    settings_from_args,
)
from fleetrl.cli.startup import collector_paused
from fleetrl.envs.catalog import check_takes_link, get_env_spec
from fleetrl.federation.schemes import DEFAULT_SCHEME
from fleetrl.federation.wire.topics import validate_id
from fleetrl.runs.setting_values import SettingError
from fleetrl.runs.settings import ALONE_SCHEME, BrokerLogin, RunSettings, as_setting_error

LAB_MISSING = (
    "fleetrl experiment: the lab is not installed; it lives beside the package in fleetrl's repository "
    "(lab/): `make install` there, or `pip install -e lab` in its development venv"
)


def build_parser() -> argparse.ArgumentParser:
    """The whole command line."""
    parser = argparse.ArgumentParser(prog="fleetrl", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    train = sub.add_parser("train", help="train a simulated fleet (individual or federated)")
    notes = {
        "broker": "unset: an embedded broker",
        "scheme": f"unset: {DEFAULT_SCHEME} ({ALONE_SCHEME} with --mode individual, where it is unused)",
    }
    add_settings_arguments(train, RunSettings, notes=notes)
    train.set_defaults(handler=cmd_train)

    demo = sub.add_parser("demo", help="the main job: a 3-unit federated QUBE run on an embedded broker")
    demo.add_argument("--out", type=Path, default=None, help="run directory (default runs/demo-<date-time>)")
    demo.add_argument("--seed", type=int, default=0)
    demo.set_defaults(handler=cmd_demo)

    evaluate = sub.add_parser("evaluate", help="run a saved policy greedily and print its mean score")
    evaluate.add_argument("model", type=Path, help="a models/worker-K.safetensors file")
    add_learning_argument(evaluate, "env")
    evaluate.add_argument("--unit", type=int, default=0)
    add_learning_argument(evaluate, "fleet_seed")
    add_fleet_profile_argument(evaluate)
    evaluate.add_argument("--episodes", type=int, default=10)
    evaluate.add_argument("--seed", type=int, default=0, help="seed of the episodes' starts (default 0)")
    add_broker_arguments(evaluate, "given: run on the unit that `fleetrl device --unit K` serves there")
    evaluate.add_argument(
        "--run-id", default="default", help="with --broker: the run id the unit's bridge serves (default)"
    )
    evaluate.set_defaults(handler=cmd_evaluate)

    homogeneity = sub.add_parser(
        "homogeneity", help="the paper's Table 2 homogeneity test on simulated units"
    )
    homogeneity.add_argument("--units", type=int, default=3)
    add_learning_argument(homogeneity, "fleet_seed")
    add_fleet_profile_argument(homogeneity)
    homogeneity.add_argument("--impulses", type=int, default=100)
    homogeneity.add_argument("--seed", type=int, default=0, help="seed of the impulse directions")
    homogeneity.add_argument("--out", type=Path, default=None, help="directory for the CSV matrices")
    homogeneity.set_defaults(handler=cmd_homogeneity)
    experiment = sub.add_parser(
        "experiment",
        help="reproduce the paper's figures and tables (the lab beside the package; its own --help)",
        add_help=False,
        prefix_chars="\x00",  # every argument, --help included, goes to the lab's own parser
    )
    experiment.add_argument("lab_args", nargs=argparse.REMAINDER)
    experiment.set_defaults(handler=cmd_experiment)
    roles.register(sub)
    device_command.register(sub)
    control_command.register(sub)
    return parser


def cmd_train(args: argparse.Namespace) -> int:
    """``fleetrl train``: every setting is checked before anything is created or started."""
    with collector_paused():
        settings = settings_from_args(RunSettings, args)
        from fleetrl.runs.launch import train
    summary = train(settings)
    from fleetrl.runs.fleet_summary import summarised

    print_summary(summary, settings.out, summarise=summarised(settings.units, settings.per_unit_detail))
    return exit_code(summary)


def exit_code(summary: dict[str, Any]) -> int:
    """A run's exit code: 130 interrupted, 1 if the chief or a worker failed or no round was played, or 0."""
    if summary.get("interrupted"):
        return 130
    failed = [w for w, info in summary["workers"].items() if str(info["state"]).startswith("failed")]
    chief_error = (summary.get("chief") or {}).get("error")
    if failed or chief_error or summary.get("rounds") == 0:
        why = [f"worker {w} failed (see logs/)" for w in failed]
        why += [f"the chief failed: {chief_error}"] if chief_error else []
        print(f"the run did not complete: {'; '.join(why) or 'no round was played'}", file=sys.stderr)
        return 1
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """``fleetrl demo``: the main job of the day."""
    with collector_paused():
        from fleetrl.runs.launch import demo_settings, train

        out = args.out or Path("runs") / time.strftime("demo-%Y%m%d-%H%M%S")
        settings = demo_settings(out, args.seed).resolved()
    summary = train(settings)
    print_summary(summary, settings.out)
    return exit_code(summary)


def duration(seconds: float) -> str:
    """``42.0 s``, ``3.5 min`` or ``2.1 h``."""
    if seconds < 120:
        return f"{seconds:.1f} s"
    return f"{seconds / 60:.1f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def print_summary(summary: dict[str, Any], out: Path, *, summarise: bool = False) -> None:
    """A run's end: a line per worker, or with ``summarise`` (a large fleet) the fleet's in a few lines."""
    print(f"run directory: {out}  ({summary['wall_seconds']:.1f} s, {summary['rounds']} rounds)")
    workers = summary["workers"]
    if summarise:
        print_fleet_summary(workers)
        workers = {}
    for worker, info in workers.items():
        done = info["completed_at_round"]
        status = f"completed at round {done}" if done is not None else f"not completed ({info['state']})"
        print(f"  worker {worker}: {status}, final WMA {wma_text(info['final_wma'])}")
    rig = summary.get("rig_seconds")
    if rig:
        bound = "" if rig["complete"] else "at least "
        units = sorted(rig["per_unit"].values())
        print(
            f"  time on real-time rigs ({rig['rule']}, {1000 * rig['period']:g} ms a step): {bound}"
            f"{duration(rig['fleet'])} until the last unit completed, median "
            f"{duration(units[len(units) // 2])} per unit"
        )
        controlled = controlled_text(rig.get("controlled"))
        if controlled:
            print(f"    {controlled}")
    print(f"  plot: {out / 'scores.png'}   metrics: {out / 'metrics.csv'}   tensorboard --logdir {out}")


def controlled_text(controlled: dict[str, float | None] | None) -> str:
    """``until 50 / 90 / 100 % of the units were controlled: 20.1 s / 41.9 s / not reached`` of summary.json's
    ``rig_seconds.controlled`` (empty without it)."""
    if not controlled:
        return ""
    shares = " / ".join(controlled)
    times = " / ".join("not reached" if s is None else duration(s) for s in controlled.values())
    return f"until {shares} % of the units were controlled: {times}"


def wma_text(wma: float | None) -> str:
    """A final WMA as shown (``-``: none)."""
    return "-" if wma is None or math.isnan(wma) else f"{wma:.1f}"


def print_fleet_summary(workers: dict[str, dict[str, Any]]) -> None:
    """A large fleet's outcome: units completed, the final WMA's quantiles, the slowest units."""
    from fleetrl.runs.fleet_summary import SLOWEST_SHOWN, wma_quantiles

    finals = [math.nan if info["final_wma"] is None else info["final_wma"] for info in workers.values()]
    done = sum(info["completed_at_round"] is not None for info in workers.values())
    p10, median, p90 = (wma_text(q) for q in wma_quantiles(finals))
    print(f"  units: {done} of {len(workers)} completed; final WMA p10 {p10}, median {median}, p90 {p90}")
    lagging = sorted(
        (w for w, info in workers.items() if info["completed_at_round"] is None),
        key=lambda w: (-math.inf if workers[w]["final_wma"] is None else workers[w]["final_wma"], int(w)),
    )
    for worker in lagging[:SLOWEST_SHOWN]:
        info = workers[worker]
        final = wma_text(info["final_wma"])
        print(f"  slowest: unit {worker} not completed ({info['state']}), final WMA {final}")
    print("  every unit: summary.json (workers), metrics.csv")


def cmd_evaluate(args: argparse.Namespace) -> int:
    """``fleetrl evaluate``."""
    from fleetrl.runs.evaluate import evaluate_model

    open_link = None if args.broker is None else bridge_link(args)
    scores = evaluate_model(
        args.model,
        args.env,
        args.unit,
        args.fleet_seed,
        args.episodes,
        args.seed,
        args.fleet_profile,
        open_link,
    )
    mean = sum(scores) / len(scores)
    result = {"model": str(args.model), "env": args.env, "unit": args.unit, "episodes": len(scores)}
    print(json.dumps(result | {"mean_score": mean, "scores": scores}))
    return 0


def bridge_link(args: argparse.Namespace) -> Callable[[], Any]:
    """``evaluate --broker URL``: its settings checked now (exit 2), and what opens a device link to the
    bridge of ``--unit`` under ``--run-id``."""
    from fleetrl.runs.factory import bridge_link as open_bridge_link
    from fleetrl.transport.mqtt import MqttTransport

    login = BrokerLogin(broker=args.broker, broker_password_file=args.broker_password_file)
    login.validate_broker()
    as_setting_error("run_id", validate_id, args.run_id, "run id")
    as_setting_error("broker", check_takes_link, get_env_spec(args.env))
    if args.fleet_profile is not None:
        raise SettingError(
            "--fleet-profile: the bridge's unit has its own dynamics; give it without --broker"
        )
    transport = MqttTransport(args.broker, password=login.broker_password)
    return lambda: open_bridge_link(args.env, args.broker, args.run_id, args.unit, transport)


def cmd_homogeneity(args: argparse.Namespace) -> int:
    """``fleetrl homogeneity``."""
    from fleetrl.runs.homogeneity_report import homogeneity_report

    report = homogeneity_report(
        args.units, args.fleet_seed, args.impulses, args.seed, args.out, args.fleet_profile
    )
    print(report)
    return 0


def cmd_experiment(args: argparse.Namespace) -> int:
    """``fleetrl experiment``: the lab's command, found through the ``fleetrl.commands`` entry point."""
    from importlib.metadata import entry_points  # lazy: 45 ms of start-up every other command would pay

    found = entry_points(group="fleetrl.commands", name="experiment")
    if not found:
        print(LAB_MISSING, file=sys.stderr)
        return 2
    lab_main: Callable[[Sequence[str]], int] = next(iter(found)).load()
    return lab_main(args.lab_args)


def _thread_failed(hook: threading.ExceptHookArgs) -> None:
    """A library's thread that dies (e.g. TensorBoard's writer on a full disk) logs one line, no traceback."""
    name = hook.thread.name if hook.thread is not None else "?"
    verbose = logging.getLogger().isEnabledFor(logging.DEBUG)
    error = hook.exc_value if verbose else None  # with -v: its traceback too
    logging.getLogger("fleetrl").error("thread %s failed: %s", name, hook.exc_value, exc_info=error)


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: Sequence[str] | None = None) -> int:
    """Parse, run, and turn known failures into one clear line and a non-zero exit code."""
    with collector_paused(freeze=False):  # the parser is garbage once it has parsed
        args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    handler: Callable[[argparse.Namespace], int] = args.handler
    logging.getLogger("fleetrl").debug("fleetrl %s: command line read", args.command)
    threading.excepthook = _thread_failed
    logging.raiseExceptions = False  # a log file on a full disk must not print tracebacks over the real error
    # SIGTERM unwinds like Ctrl-C, stopping what this command started; SIGINT is re-armed (a process started
    # in the background inherits it ignored).
    signal.signal(signal.SIGTERM, _terminate)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return handler(args)
    except (ValueError, FileNotFoundError, FileExistsError) as err:  # a setting or a file: exit 2
        print(f"fleetrl {args.command}: error: {err}", file=sys.stderr)
        return 2
    except OSError as err:  # the command could not do its job (broker, nobody came, disk): exit 1
        logging.getLogger("fleetrl").debug("the error's traceback", exc_info=True)  # with -v
        print(f"fleetrl {args.command}: error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
