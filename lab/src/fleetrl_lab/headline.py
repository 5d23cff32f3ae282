"""README's results table, generated from the committed run records like docs/results.md (one source).

Each row divides a fleet by one unit alone on held-out seeds, in rounds and time on the rigs; ``make report``
writes the table between README's markers.
"""

import argparse
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from fleetrl_lab.arms import FULL, Arm
from fleetrl_lab.catalog import PLANS
from fleetrl_lab.plan import Ratio, bound_mark, fleet_rounds, rig_minutes, seed_range, unit_rounds
from fleetrl_lab.records import RunRecord, read_record, record_path
from fleetrl_lab.stats import markdown_table

BEGIN = "<!-- results table: written by `make report` from lab/records; do not edit -->"
END = "<!-- end of the results table -->"


@dataclass(frozen=True)
class Row:
    """A README row: ``ratio``'s two arms on ``seeds``."""

    task: str
    ratio: Ratio
    seeds: range
    note: str = ""
    """a footnote (e.g. seeds that informed a choice)"""


def _pick(plan: str, label: str, fleet_seed: int = 0) -> Arm:
    arms = PLANS[plan](replace(FULL, fleet_seed=fleet_seed)).arms
    found = [a for a in arms if a.label == label]
    if len(found) != 1:
        raise ValueError(f"experiment {plan!r} has no arm labelled {label!r}")
    return found[0]


def _row(
    task: str, plan: str, alone: str, fleet: str, seeds: range, fleet_seed: int = 0, note: str = ""
) -> Row:
    pair = Ratio(_pick(plan, alone, fleet_seed), _pick(plan, fleet, fleet_seed), task)
    return Row(task, pair, seeds, note)


REUSED = "seeds 100–104 also showed the stuck units that chose this arm's update (docs/results.md)"


def rows() -> list[Row]:
    """The README's rows, in order."""
    ten, five = range(100, 110), range(100, 105)
    alone, pergrad = "individual · standard", "federated · standard · pergrad"
    cartpole = "{} workers · standard · pergrad"
    large = "{} · pergrad · large-fleet settings"
    return [
        _row("3 QUBE units, fleet seed 0", "fig5", alone, pergrad, ten),
        _row("3 QUBE units, fleet seed 1", "fig5", alone, pergrad, ten, fleet_seed=1),
        _row("CartPole, 1 → 8 workers", "cartpole-scaling", cartpole.format(1), cartpole.format(8), ten),
        _row(
            "CartPole, 1 → 1,000 units, large-fleet settings on both",
            "fleet-scale",
            large.format("1 unit alone"),
            large.format("1000 units"),
            five,
        ),
        _row(
            "QUBE, 1 → 1,000 units",
            "qube-scale",
            "1 unit alone · pergrad",
            "1000 units · pergrad",
            five,
            note=REUSED,
        ),
    ]


def _records(arm: Arm, seeds: range, records: Path) -> list[RunRecord]:
    found = [read_record(record_path(records, arm.key, s)) for s in seeds]
    missing = [s for s, r in zip(seeds, found, strict=True) if r is None]
    if missing:
        raise FileNotFoundError(f"{arm.label}: no record of seed(s) {seed_range(missing)} in {records}")
    return [r for r in found if r is not None]


def _figures(runs: list[RunRecord]) -> tuple[float, ...]:
    """Medians: rounds until the last unit completed, rounds per unit, and the same in minutes on the rigs."""
    rig = rig_minutes(runs)
    if rig is None:
        raise ValueError("a headline run without time on the rigs")
    figures = (fleet_rounds(runs), unit_rounds(runs), *rig)
    return tuple(float(np.median(values)) for values in figures)


def headline_table(records: Path) -> str:
    """README's results table from ``records`` (a missing record is an error)."""
    header = [
        "task (held-out seeds)",
        "rounds, last unit: alone → fleet",
        "rounds per unit: alone → fleet",
        "minutes on the rigs, last unit: alone → fleet",
        "minutes on the rigs per unit: alone → fleet",
        "speed-up, last unit / per unit: rounds · time",
    ]
    body: list[list[str]] = []
    notes: list[str] = []
    for row in rows():
        slower = _records(row.ratio.slower, row.seeds, records)
        faster = _records(row.ratio.faster, row.seeds, records)
        a, b = _figures(slower), _figures(faster)
        at_least = [
            "≥ " if not all(r.completion().complete for r in runs) else "" for runs in (slower, faster)
        ]
        ratio = bound_mark(slower, faster)
        mark = ""
        if row.note:
            notes.append(f"{'†' * (len(notes) + 1)} {row.note}")
            mark = "†" * len(notes)
        body.append(
            [
                f"{row.task} ({seed_range(row.seeds)}{mark})",
                f"{at_least[0]}{a[0]:g} → {at_least[1]}{b[0]:g}",
                f"{at_least[0]}{a[1]:g} → {at_least[1]}{b[1]:g}",
                f"{at_least[0]}{a[2]:.1f} → {at_least[1]}{b[2]:.1f}",
                f"{at_least[0]}{a[3]:.1f} → {at_least[1]}{b[3]:.1f}",
                f"{ratio}{a[0] / b[0]:.2f}× / {ratio}{a[1] / b[1]:.2f}× · "
                f"{ratio}{a[2] / b[2]:.2f}× / {ratio}{a[3] / b[3]:.2f}×",
            ]
        )
    if any("≥" in cell for line in body for cell in line[1:]):
        notes.append(
            "≥: some runs of the arm did not complete within M and count as M, so the figure is a bound"
        )
    table = markdown_table(header, body)
    return "\n\n".join([table.rstrip(), *notes]) + "\n"


def replace_table(text: str, table: str) -> str:
    """``text`` with what lies between its markers replaced by ``table``."""
    pattern = re.compile(re.escape(BEGIN) + r"\n.*?" + re.escape(END), re.DOTALL)
    if not pattern.search(text):
        raise ValueError("README has no results-table markers")
    return pattern.sub(lambda _: f"{BEGIN}\n{table}{END}", text, count=1)


def table_in(text: str) -> str:
    """What lies between the markers of ``text``."""
    start, end = text.index(BEGIN) + len(BEGIN) + 1, text.index(END)
    return text[start:end]


def main(argv: list[str] | None = None) -> None:
    """``python -m fleetrl_lab.headline --records DIR --readme README.md``"""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=Path, required=True)
    parser.add_argument("--readme", type=Path, required=True)
    args = parser.parse_args(argv)
    args.readme.write_text(replace_table(args.readme.read_text(), headline_table(args.records)))


if __name__ == "__main__":
    main()
