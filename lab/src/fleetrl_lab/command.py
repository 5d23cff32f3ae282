"""``fleetrl experiment``: the lab's command, reached by the product through the ``fleetrl.commands`` entry
point (the product never imports the lab)."""

import argparse
from collections.abc import Sequence
from pathlib import Path

from fleetrl.cli.settings_args import add_target_score_argument
from fleetrl_lab.runner import publish_report, run_experiment


def build_parser() -> argparse.ArgumentParser:
    """``fleetrl experiment``'s options."""
    experiment = argparse.ArgumentParser(
        prog="fleetrl experiment", description="reproduce the paper's figures and tables; writes report.md"
    )
    experiment.add_argument(
        "name",
        help="fig5, fig6, cartpole-scaling, learning, continuous, uneven, argmax, fleet-scale, qube-scale, "
        "table2, peers, or all (but uneven, argmax, fleet-scale and qube-scale)",
    )
    experiment.add_argument(
        "--seeds", type=int, default=10, help="how many learning seeds the headline arms run on (default 10)"
    )
    experiment.add_argument(
        "--other-seeds",
        type=int,
        default=None,
        help="how many of those seeds the other arms run on (default: all; make results uses 5)",
    )
    experiment.add_argument(
        "--headline-only",
        action="store_true",
        help="run only the headline arms (each unit alone, fedavg, pergrad), e.g. on another --fleet-seed",
    )
    experiment.add_argument(
        "--first-seed",
        type=int,
        default=100,
        help="the first learning seed (default 100: seeds 0-9 are for tuning, never reported)",
    )
    experiment.add_argument(
        "--fleet-seed", type=int, default=0, help="fleet of every arm (default 0: the tuning fleet)"
    )
    experiment.add_argument(
        "--out", type=Path, default=Path("runs/experiments"), help="run directories and the report"
    )
    experiment.add_argument(
        "--records",
        type=Path,
        default=None,
        help="the runs' small JSON records, from which the report is computed (default OUT/records)",
    )
    experiment.add_argument(
        "--env",
        default=None,
        metavar="ENV",
        help="learning and cartpole-scaling on your own unit type (package.module:factory) instead of the "
        "built-ins, for the CartPole budget of rounds",
    )
    add_target_score_argument(experiment)
    experiment.add_argument("--quick", action="store_true", help="tiny budgets: checks the pipeline only")
    experiment.add_argument(
        "--from-records",
        action="store_true",
        help="run nothing: build the report from the records there are (missing seeds are left out, an arm "
        "without any is shown as not run yet)",
    )
    experiment.add_argument(
        "--publish", type=Path, default=None, help="also copy report.md (and its images) to this file"
    )
    return experiment


def main(argv: Sequence[str]) -> int:
    """Run ``fleetrl experiment`` with the arguments after the command's name."""
    args = build_parser().parse_args(argv)
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    report = run_experiment(
        args.name,
        args.out,
        seeds,
        args.quick,
        args.records,
        args.fleet_seed,
        args.other_seeds,
        args.headline_only,
        args.env,
        args.target_score,
        run=not args.from_records,
    )
    print(f"report: {report}")
    if args.publish is not None:
        print(f"published: {publish_report(args.out, args.publish)}")
    return 0
