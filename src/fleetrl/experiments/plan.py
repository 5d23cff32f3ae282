"""A training experiment: arms × seeds, run as a sweep, summarised as CSV, plots and a report section."""

import csv
import logging
from dataclasses import dataclass, field, replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from fleetrl.experiments.arms import Arm, completions, mean_score_curve, same_scores, wall_seconds
from fleetrl.experiments.stats import bootstrap_ratio, markdown_table, spread
from fleetrl.experiments.sweep import run_all
from fleetrl.runs.plots import X_LABELS, by_worker, draw_worker
from fleetrl.runs.records import read_metrics

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Ratio:
    """A speed-up to report: median fleet rounds of ``slower`` / of ``faster``."""

    slower: Arm
    faster: Arm
    claim: str
    """what the paper reports for it (or what we aim at)"""


@dataclass
class Plan:
    """What one experiment runs and how its report reads."""

    name: str
    title: str
    arms: list[Arm]
    max_rounds: int
    ratios: list[Ratio] = field(default_factory=list)
    side_by_side: tuple[Arm, Arm] | None = None
    """two arms whose first seed is drawn worker by worker, next to each other (Fig. 5 a/b)"""
    mqtt_check: Arm | None = None
    """an arm run over the local bus that is run once more over MQTT, to show the numbers do not change"""
    notes: str = ""


def run_plan(plan: Plan, out: Path, seeds: list[int], command: str) -> str:
    """Run every arm for every seed and return the report section (markdown).

    Runs live in ``out/runs/<arm key>/seed-<seed>``, shared by every experiment (an arm two experiments
    have in common runs once); finished runs are reused. The section's files go to ``out/<plan name>/``.
    """
    runs_root = out / "runs"
    root = out / plan.name
    root.mkdir(parents=True, exist_ok=True)
    runs = {arm.key: arm.runs(runs_root, seeds) for arm in plan.arms}
    extra = []
    if plan.mqtt_check:
        local_arm = plan.mqtt_check
        mqtt_arm = replace(local_arm, key=f"{local_arm.key}-mqtt", args=_over_mqtt(local_arm.args))
        extra = [mqtt_arm.run(runs_root, seeds[0])]
    run_all([r for rs in runs.values() for r in rs] + extra)

    rows = []
    for key, arm_runs in runs.items():
        for run, completion, wall in zip(
            arm_runs, completions(arm_runs), wall_seconds(arm_runs), strict=True
        ):
            rows.append(
                [
                    key,
                    run.labels["seed"],
                    completion.fleet,
                    completion.complete,
                    ";".join(str(r) for r in completion.worker_rounds()),
                    round(wall, 1),
                ]
            )
    with (root / "runs.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["arm", "seed", "fleet_rounds", "all_completed", "worker_rounds", "wall_seconds"])
        writer.writerows(rows)

    lines = [f"## {plan.title}", "", f"Command: `{command}`", ""]
    if plan.notes:
        lines += [plan.notes, ""]
    lines += [_arms_table(plan, runs), ""]
    for ratio in plan.ratios:
        slower = completions(runs[ratio.slower.key])
        faster = completions(runs[ratio.faster.key])
        point, low, high = bootstrap_ratio([c.fleet for c in slower], [c.fleet for c in faster])
        per_unit = bootstrap_ratio(
            [r for c in slower for r in c.worker_rounds()], [r for c in faster for r in c.worker_rounds()]
        )
        # an arm whose runs hit M without completing gives a bound, not a ratio (both: no direction)
        censored = (not all(c.complete for c in slower), not all(c.complete for c in faster))
        bound = {(False, False): "", (True, False): "≥ ", (False, True): "≤ ", (True, True): "~"}[censored]
        lines.append(
            f"- **{ratio.slower.label} → {ratio.faster.label}**: fleet speed-up "
            f"{bound}{point:.2f}× (95 % bootstrap {low:.2f}–{high:.2f}), per unit {bound}{per_unit[0]:.2f}× "
            f"({per_unit[1]:.2f}–{per_unit[2]:.2f}); {ratio.claim}"
        )
    if extra:
        assert plan.mqtt_check is not None
        identical = same_scores(runs[plan.mqtt_check.key][0].out, extra[0].out)
        lines.append(
            f"- Transport check: seed {seeds[0]} of {plan.mqtt_check.label} over MQTT (embedded broker): "
            f"scores {'identical' if identical else 'DIFFERENT'} to the in-process bus."
        )
    curves = root / "mean_score.png"
    _plot_curves(plan, runs, curves)
    lines += ["", f"![mean score per round]({curves.relative_to(out)})"]
    if plan.side_by_side:
        fig = root / "workers.png"
        _plot_side_by_side(plan, runs, fig)
        lines += ["", f"![per-worker curves, seed {seeds[0]}]({fig.relative_to(out)})"]
    lines += ["", f"Regenerate one arm (SEEDS: {' '.join(map(str, seeds))}):", ""]
    lines += [f"    {arm.command(runs_root)}" for arm in plan.arms]
    return "\n".join(lines) + "\n"


def _over_mqtt(args: tuple[str, ...]) -> tuple[str, ...]:
    out = list(args)
    index = out.index("--transport")
    out[index + 1] = "mqtt"
    return tuple(out)


def _arms_table(plan: Plan, runs: dict[str, list]) -> str:
    rows = []
    for arm in plan.arms:
        done = completions(runs[arm.key])
        fleet = spread([c.fleet for c in done])
        unit = spread([r for c in done for r in c.worker_rounds()])
        walls = spread(wall_seconds(runs[arm.key]))
        complete = sum(c.complete for c in done)
        rows.append([arm.label, str(fleet), str(unit), f"{complete}/{len(done)}", f"{walls.median:.1f}"])
    header = [
        "arm",
        "rounds until the last unit completes, median [IQR] (range)",
        "rounds per unit, median [IQR] (range)",
        "runs complete within M",
        "wall s (median)",
    ]
    return markdown_table(header, rows)


def _plot_curves(plan: Plan, runs: dict[str, list], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(8, 4))
    for arm in plan.arms:
        ax.plot(mean_score_curve(runs[arm.key], plan.max_rounds), label=arm.label, lw=1.2)
    ax.set_xlabel(X_LABELS["rounds"])
    ax.set_ylabel("mean score (all workers, all seeds)")
    ax.set_title(plan.title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_side_by_side(plan: Plan, runs: dict[str, list], path: Path) -> None:
    assert plan.side_by_side is not None
    columns = [by_worker(read_metrics(runs[arm.key][0].out / "metrics.csv")) for arm in plan.side_by_side]
    n_rows = max(len(c) for c in columns)
    fig, axes = plt.subplots(n_rows, 2, figsize=(12, 2.4 * n_rows), sharex=True, sharey=True, squeeze=False)
    for col, (arm, groups) in enumerate(zip(plan.side_by_side, columns, strict=True)):
        axes[0, col].set_title(arm.label, fontsize=10)
        for row, (worker, records) in enumerate(groups.items()):
            draw_worker(axes[row, col], records, f"worker {worker}")
    axes[0, 0].legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
