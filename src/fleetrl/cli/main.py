"""``fleetrl``: train a simulated fleet, evaluate a policy, test the fleet's homogeneity, run roles."""

import argparse
import json
import logging
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from fleetrl.cli import device_command, roles
from fleetrl.cli.parsing import parse_overrides


class UsageError(Exception):
    """A command-line mistake: printed as one line, exit code 2."""


class RunFailed(Exception):
    """The command ran but did not do its job (e.g. no worker played a round): one line, exit code 1."""


def add_train_arguments(p: argparse.ArgumentParser) -> None:
    """The options shared by ``train`` and ``demo``."""
    p.add_argument("--env", default="qube", help="qube (QUBE-Servo 2 balance) or cartpole")
    p.add_argument("--units", type=int, default=3, help="units in the fleet, one worker each (default 3)")
    p.add_argument("--preset", default="paper", help="PPO preset: paper (Table 1) or standard")
    p.add_argument("--seed", type=int, default=0, help="learning seed (default 0)")
    p.add_argument(
        "--fleet-seed", type=int, default=0, help="seed of the fleet's per-unit dynamics (default 0)"
    )
    p.add_argument("--max-rounds", type=int, default=1000, help="the paper's M: most rounds per worker")
    p.add_argument("--out", type=Path, required=True, help="run directory to create")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one PPO setting of the preset, e.g. --set clip_eps=0.2 (repeatable)",
    )
    p.add_argument("--no-live", action="store_true", help="no live terminal view")


def build_parser() -> argparse.ArgumentParser:
    """The whole command line."""
    parser = argparse.ArgumentParser(prog="fleetrl", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    train = sub.add_parser("train", help="train a simulated fleet (individual or federated)")
    add_train_arguments(train)
    train.add_argument("--mode", default="federated", help="individual or federated (default)")
    train.add_argument("--transport", default="mqtt", help="federated: mqtt (default) or local")
    train.add_argument(
        "--broker", default=None, help="mqtt://[user:pass@]host:port; default: embedded broker"
    )
    train.add_argument(
        "--device-link",
        default="inprocess",
        help="inprocess (default) or mqtt: each unit served by a device bridge over the broker",
    )
    train.add_argument(
        "--scheme",
        default="paper",
        help="federated: paper (default; gradient sharing + model transfer) or fedavg (model averaging)",
    )
    train.add_argument(
        "--aggregation",
        default="mean",
        help="federated: mean (default), median, trimmed_mean[:β] or clipped_mean[:C]",
    )
    train.add_argument(
        "--quorum",
        type=float,
        default=1.0,
        help="federated: close a round at the deadline with this fraction of W (default 1.0)",
    )
    train.add_argument(
        "--round-timeout",
        type=float,
        default=None,
        help="federated: round deadline in seconds (default: wait for every worker)",
    )
    train.set_defaults(handler=cmd_train)

    demo = sub.add_parser("demo", help="the main job: a 3-unit federated QUBE run on an embedded broker")
    demo.add_argument("--out", type=Path, default=None, help="run directory (default runs/demo-<date-time>)")
    demo.add_argument("--seed", type=int, default=0)
    demo.set_defaults(handler=cmd_demo)

    evaluate = sub.add_parser("evaluate", help="run a saved policy greedily and print its mean score")
    evaluate.add_argument("model", type=Path, help="a models/worker-K.safetensors file")
    evaluate.add_argument("--env", default="qube")
    evaluate.add_argument("--unit", type=int, default=0)
    evaluate.add_argument("--fleet-seed", type=int, default=0)
    evaluate.add_argument("--episodes", type=int, default=10)
    evaluate.add_argument("--seed", type=int, default=0)
    evaluate.set_defaults(handler=cmd_evaluate)

    homogeneity = sub.add_parser(
        "homogeneity", help="the paper's Table 2 homogeneity test on simulated units"
    )
    homogeneity.add_argument("--units", type=int, default=3)
    homogeneity.add_argument("--fleet-seed", type=int, default=0)
    homogeneity.add_argument("--impulses", type=int, default=100)
    homogeneity.add_argument("--seed", type=int, default=0, help="seed of the impulse directions")
    homogeneity.add_argument("--out", type=Path, default=None, help="directory for the CSV matrices")
    homogeneity.set_defaults(handler=cmd_homogeneity)
    experiment = sub.add_parser(
        "experiment", help="reproduce the paper's figures and tables; writes report.md"
    )
    experiment.add_argument("name", help="fig5, fig6, cartpole-scaling, table2, peers, or all")
    experiment.add_argument("--seeds", type=int, default=5, help="how many seeds (default 5)")
    experiment.add_argument("--first-seed", type=int, default=0)
    experiment.add_argument("--out", type=Path, default=Path("runs/experiments"))
    experiment.add_argument("--quick", action="store_true", help="tiny budgets: checks the pipeline only")
    experiment.add_argument(
        "--publish", type=Path, default=None, help="also copy report.md (and its images) to this file"
    )
    experiment.set_defaults(handler=cmd_experiment)
    roles.register(sub)
    device_command.register(sub)
    return parser


def run_settings(args: argparse.Namespace, mode: str) -> Any:
    """RunSettings from parsed arguments."""
    from fleetrl.runs.settings import RunSettings

    return RunSettings(
        mode=mode,
        env=args.env,
        units=args.units,
        preset=args.preset,
        seed=args.seed,
        max_rounds=args.max_rounds,
        out=args.out,
        fleet_seed=args.fleet_seed,
        transport=getattr(args, "transport", "mqtt"),
        broker=getattr(args, "broker", None),
        device_link=getattr(args, "device_link", "inprocess"),
        scheme=getattr(args, "scheme", "paper"),
        aggregation=getattr(args, "aggregation", "mean"),
        quorum=getattr(args, "quorum", 1.0),
        round_timeout=getattr(args, "round_timeout", None),
        overrides=parse_overrides(args.overrides),
        live=not args.no_live,
    )


def cmd_train(args: argparse.Namespace) -> int:
    """``fleetrl train``."""
    settings = run_settings(args, args.mode)
    settings.validate()
    if (settings.out / "metrics.csv").exists():
        raise UsageError(f"{settings.out} already holds a run; choose another --out")
    from fleetrl.runs.launch import train

    summary = train(settings)
    print_summary(summary, settings.out)
    return exit_code(summary)


def exit_code(summary: dict[str, Any]) -> int:
    """A run's exit code: 130 interrupted, 1 if the chief or any worker failed (or no round was played),
    else 0 — so a script or CI can trust it."""
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
    from fleetrl.runs.launch import demo_settings, train

    out = args.out or Path("runs") / time.strftime("demo-%Y%m%d-%H%M%S")
    settings = demo_settings(out, args.seed)
    if (settings.out / "metrics.csv").exists():
        raise UsageError(f"{settings.out} already holds a run; remove it or pass --out DIR")
    summary = train(settings)
    print_summary(summary, settings.out)
    return exit_code(summary)


def print_summary(summary: dict[str, Any], out: Path) -> None:
    """What a person wants to see when a run ends."""
    print(f"run directory: {out}  ({summary['wall_seconds']:.1f} s, {summary['rounds']} rounds)")
    for worker, info in summary["workers"].items():
        done = info["completed_at_round"]
        wma = info["final_wma"]
        wma_text = "-" if wma is None else f"{wma:.1f}"
        status = f"completed at round {done}" if done is not None else f"not completed ({info['state']})"
        print(f"  worker {worker}: {status}, final WMA {wma_text}")
    print(f"  plot: {out / 'scores.png'}   metrics: {out / 'metrics.csv'}   tensorboard --logdir {out}")


def cmd_evaluate(args: argparse.Namespace) -> int:
    """``fleetrl evaluate``."""
    from fleetrl.runs.evaluate import evaluate_model

    scores = evaluate_model(args.model, args.env, args.unit, args.fleet_seed, args.episodes, args.seed)
    mean = sum(scores) / len(scores)
    print(
        json.dumps(
            {
                "model": str(args.model),
                "env": args.env,
                "unit": args.unit,
                "episodes": len(scores),
                "mean_score": mean,
                "scores": scores,
            }
        )
    )
    return 0


def cmd_homogeneity(args: argparse.Namespace) -> int:
    """``fleetrl homogeneity``."""
    from fleetrl.runs.homogeneity_report import homogeneity_report

    print(homogeneity_report(args.units, args.fleet_seed, args.impulses, args.seed, args.out))
    return 0


def cmd_experiment(args: argparse.Namespace) -> int:
    """``fleetrl experiment``."""
    from fleetrl.experiments.runner import run_experiment

    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    report = run_experiment(args.name, args.out, seeds, args.quick)
    print(f"report: {report}")
    if args.publish is not None:
        from fleetrl.experiments.runner import publish_report

        print(f"published: {publish_report(args.out, args.publish)}")
    return 0


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: Sequence[str] | None = None) -> int:
    """Parse, run, and turn known failures into one clear line and a non-zero exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    handler: Callable[[argparse.Namespace], int] = args.handler
    # SIGTERM unwinds like Ctrl-C: brokers, bridges and worker processes this command started are stopped.
    # SIGINT is re-armed too: a process started in the background inherits it ignored, and Ctrl-C (or the
    # launcher's stop request) must still end a run cleanly.
    signal.signal(signal.SIGTERM, _terminate)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return handler(args)
    except (UsageError, ValueError, FileNotFoundError, FileExistsError) as err:
        print(f"fleetrl {args.command}: error: {err}", file=sys.stderr)
        return 2
    except (TimeoutError, ConnectionError, RunFailed) as err:  # the command could not do its job
        print(f"fleetrl {args.command}: error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
