"""A training experiment (:class:`Plan`): arms × seeds, run as a sweep, summarised from the runs' records as
CSV, plots and a report section."""

import csv
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from fleetrl.runs.rig_time import CONTROLLED_SHARES, RigTime
from fleetrl_lab.arms import Arm, Places
from fleetrl_lab.figures import plot_curves, plot_side_by_side
from fleetrl_lab.records import RunRecord
from fleetrl_lab.rig_phases import phases_lines
from fleetrl_lab.stats import Completion, bootstrap_median, bootstrap_ratio, markdown_table
from fleetrl_lab.sweep import Run, run_all
from fleetrl_lab.throughput import throughput_lines


@dataclass(frozen=True)
class Ratio:
    """A speed-up to report: median fleet rounds of ``slower`` / of ``faster``."""

    slower: Arm
    faster: Arm
    claim: str
    """what the paper reports (or what we aim at)"""

    def __post_init__(self) -> None:
        if self.slower.criterion != self.faster.criterion:
            raise ValueError(
                f"ratio {self.slower.label!r} → {self.faster.label!r} divides criterion "
                f"{self.slower.criterion!r} by {self.faster.criterion!r}: compare arms of one criterion"
            )


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
    """an arm run once more over MQTT, to show the numbers do not change"""
    notes: str = ""
    rig_phases: bool = False
    """the report says where each unit's time on the rigs goes (:mod:`.rig_phases`)"""
    throughput: bool = False
    """the report says what each arm cost the machine (:mod:`.throughput`)"""
    seed_history: str = ""
    """which held-out seed sets informed which choice of this plan's arms (empty: none did)"""
    headline: list[Arm] = field(default_factory=list)
    """the arms run on every seed; the others may run on fewer (``other_seeds`` of :func:`run_plan`)"""

    def seeds_of(self, arm: Arm, seeds: list[int], other_seeds: int | None) -> list[int]:
        """All of ``seeds`` for a headline arm (or if ``other_seeds`` is None), else the first
        ``other_seeds``."""
        if other_seeds is None or any(arm is h for h in self.headline):
            return seeds
        return seeds[:other_seeds]

    def headline_only(self) -> "Plan":
        """The plan cut down to its headline arms and the comparisons among them."""
        kept = self.headline or self.arms

        def has(arm: Arm | None) -> bool:
            return arm is not None and any(arm is k for k in kept)

        return replace(
            self,
            name=f"{self.name}-headline",
            title=f"{self.title}: headline arms",
            arms=[a for a in self.arms if has(a)],
            ratios=[r for r in self.ratios if has(r.slower) and has(r.faster)],
            side_by_side=self.side_by_side if all(map(has, self.side_by_side or [None])) else None,
            mqtt_check=self.mqtt_check if has(self.mqtt_check) else None,
        )


NOT_RUN = "not run yet"
Records = dict[str, list[RunRecord]]
"""each arm's records (by arm key), one per seed"""


def run_plan(
    plan: Plan,
    out: Path,
    places: Places,
    seeds: list[int],
    preamble: list[str],
    other_seeds: int | None = None,
    run: bool = True,
) -> str:
    """Run every arm's seeds not done yet, seed by seed across the arms, and return the report section
    (markdown), computed from the records alone; its files go to ``out/<plan name>/``. With ``run`` False
    nothing runs and an arm's missing seeds are left out. ``preamble``: the lines after its title."""
    root = out / plan.name
    root.mkdir(parents=True, exist_ok=True)
    runs = {arm.key: arm.runs(places, plan.seeds_of(arm, seeds, other_seeds)) for arm in plan.arms}
    mqtt_arm = plan.mqtt_check.with_settings(transport="mqtt") if plan.mqtt_check else None
    extra = [mqtt_arm.run(places, seeds[0])] if mqtt_arm else []
    if run:
        run_all(_seed_major(list(runs.values())) + extra)
    else:
        runs = {key: [r for r in arm_runs if r.done] for key, arm_runs in runs.items()}
        extra = [r for r in extra if r.done]
    records = {key: [run.result() for run in arm_runs] for key, arm_runs in runs.items()}
    _write_csv(root / "runs.csv", records)

    lines = [f"## {plan.title}", "", *preamble]
    if plan.notes:
        lines += [plan.notes, ""]
    lines += [_arms_table(plan, records), "", RIG_TIME_NOTE, "", *episode_lines(plan, records)]
    speed = _speed_up_table(plan, records)
    if speed:
        lines += [speed, ""]
    lines += [_ratio_line(ratio, records) for ratio in plan.ratios]
    if plan.rig_phases:
        lines += phases_lines([(arm.label, records[arm.key]) for arm in plan.arms])
    if plan.throughput:
        lines += throughput_lines([(arm.label, records[arm.key]) for arm in plan.arms])
    local = records[plan.mqtt_check.key] if plan.mqtt_check else []
    if extra and plan.mqtt_check and local and local[0].result_settings["seed"] == seeds[0]:
        lines.append(transport_check_line(plan.mqtt_check.label, seeds[0], local[0], extra[0].result()))
    hosts = sorted({r.host for rs in records.values() for r in rs})
    lines += ["", "Runs made on: " + "; ".join(f"`{h}`" for h in hosts) + "."]
    curves = root / "mean_score.png"
    plot_curves([(arm.label, records[arm.key]) for arm in plan.arms], plan.max_rounds, plan.title, curves)
    lines += ["", f"![mean score per round]({curves.relative_to(out)})"]
    if plan.side_by_side and all(records[arm.key] for arm in plan.side_by_side):
        fig = root / "workers.png"
        plot_side_by_side([(arm.label, records[arm.key][0]) for arm in plan.side_by_side], fig)
        first = records[plan.side_by_side[0].key][0].result_settings["seed"]
        lines += ["", f"![per-worker curves, seed {first}]({fig.relative_to(out)})"]
    listed = " ".join(map(str, seeds))
    lines += ["", f"Regenerate one arm (SEEDS: the arm's seeds in the table above, of {listed}):", ""]
    lines += [f"    {arm.command(places.runs)}" for arm in plan.arms]
    return "\n".join(lines) + "\n"


def _seed_major(runs_by_arm: list[list[Run]]) -> list[Run]:
    """Every arm's first run, then every arm's second, ..."""
    longest = max((len(runs) for runs in runs_by_arm), default=0)
    return [runs[i] for i in range(longest) for runs in runs_by_arm if i < len(runs)]


def _write_csv(path: Path, records: Records) -> None:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["arm", "seed", "fleet_rounds", "all_completed", "worker_rounds", "wall_seconds"])
        for key, arm_records in records.items():
            for record in arm_records:
                seed = record.result_settings["seed"]
                completion = record.completion()
                rounds = ";".join(str(r) for r in completion.worker_rounds())
                writer.writerow(
                    [key, seed, completion.fleet, completion.complete, rounds, record.wall_seconds]
                )


def completions(records: list[RunRecord]) -> list[Completion]:
    """Rounds to completion of each run."""
    return [record.completion() for record in records]


def bound_mark(slower: list[RunRecord], faster: list[RunRecord]) -> str:
    """``≥ ``, ``≤ `` or ``~`` where the slower, the faster or both arms have runs that hit M uncompleted."""
    censored = (
        not all(c.complete for c in completions(slower)),
        not all(c.complete for c in completions(faster)),
    )
    return {(False, False): "", (True, False): "≥ ", (False, True): "≤ ", (True, True): "~"}[censored]


def fleet_rounds(records: list[RunRecord]) -> list[int]:
    """Each run's rounds until its last unit completed."""
    return [c.fleet for c in completions(records)]


def unit_rounds(records: list[RunRecord]) -> list[int]:
    """Every unit's rounds to completion, over every run."""
    return [r for c in completions(records) for r in c.worker_rounds()]


RIG_TIME_NOTE = (
    "Time on the rigs: what the run would take on real-time units, one accounting for every arm"
    " (`fleetrl.runs.rig_time`). A unit's clock runs while it plays (QUBE 6 ms a step, CartPole 20 ms), while"
    " it is reset before each episode (a QUBE unit's swing-up: the mean of 10 seeded resets of its simulated"
    " device, 1.3–3.6 s a unit on fleet seeds 0 and 1; one that does not settle is put upright by hand,"
    " charged 30 s more; CartPole 0), while it is absent (its draws replayed from the seed, each k rounds'"
    " worth of its own last round) and while it waits for the fleet: under a round barrier a round closes"
    " when the last unit that contributed to it is ready (with `pergrad`'s quorum, at the deadline — the"
    " quorum plus its grace — when a unit it waited for missed it); a straggler's episode overlaps the rounds"
    " it missed. Each unit alone and `fedasync` wait for nobody. Computing is left out (a slow unit computes"
    " slower, its device's period unchanged: what it costs is the rounds it missed and the grace given to"
    " it). The fleet's clock runs until its last unit completes; its time until 50, 90 and 100 % of its N"
    " units complete is when, on that one clock, the ⌈share·N⌉-th unit's criterion held (the median over an"
    " arm's runs, marked ≥ where a run never reached the share: that run counts its whole time). Records made"
    " before runs kept their steps read each round's steps from its score (reward 1 per step, at most one"
    " step short per episode)."
)


def _rig_times(records: list[RunRecord]) -> list[RigTime] | None:
    """Each run's time on the rigs (None if there are no runs or one's is unknown)."""
    times = [r.rig_time() for r in records]
    known = [t for t in times if t is not None]
    return known if times and len(known) == len(times) else None


def rig_minutes(records: list[RunRecord]) -> tuple[list[float], list[float]] | None:
    """Minutes on the rigs of an arm's runs: until each run's last unit completed, and per unit (None if
    unknown)."""
    times = _rig_times(records)
    if times is None:
        return None
    return [t.fleet / 60 for t in times], [s / 60 for t in times for s in t.per_unit.values()]


def controlled_minutes(records: list[RunRecord]) -> str:
    """Median minutes on the rigs until 50, 90 and 100 % of a run's units completed (``2.0 / ≥ 4.0 / ≥ 4.0``:
    a run that never reached a share counts its whole time and marks the median ≥); "-" if unknown."""
    times = _rig_times(records)
    if times is None:
        return "-"
    shown = []
    for share in CONTROLLED_SHARES:
        reached = [(t.until_controlled(share), t.fleet) for t in times]
        minutes = [(whole if s is None else s) / 60 for s, whole in reached]
        bound = "≥ " if any(s is None for s, _ in reached) else ""
        shown.append(f"{bound}{float(np.median(minutes)):.1f}")
    return " / ".join(shown)


def _times(bound: str, ratio: tuple[float, float, float]) -> str:
    """``≥ 1.59× (1.10–2.30)``: a speed-up and its 95 % bootstrap interval."""
    point, low, high = ratio
    return f"{bound}{point:.2f}× ({low:.2f}–{high:.2f})"


def _rig_ratio(slower: list[RunRecord], faster: list[RunRecord]) -> str:
    """Speed-up in time on the rigs, fleet / per unit ("-" if unknown)."""
    a, b = rig_minutes(slower), rig_minutes(faster)
    if a is None or b is None:
        return "-"
    bound = bound_mark(slower, faster)
    return f"{_times(bound, bootstrap_ratio(a[0], b[0]))} / {_times(bound, bootstrap_ratio(a[1], b[1]))}"


def on_shared_seeds(
    slower: list[RunRecord], faster: list[RunRecord]
) -> tuple[list[RunRecord], list[RunRecord], str]:
    """The runs of two arms on the seeds both have, and a note naming those seeds when they differ."""
    seeds = [{int(r.result_settings["seed"]) for r in arm} for arm in (slower, faster)]
    shared = seeds[0] & seeds[1]
    if seeds[0] == seeds[1]:
        return slower, faster, ""
    kept = [[r for r in arm if int(r.result_settings["seed"]) in shared] for arm in (slower, faster)]
    return kept[0], kept[1], f" (on seeds {_seeds(kept[0]) or 'none'}, the seeds both arms have)"


def _ratio_line(ratio: Ratio, records: Records) -> str:
    if not records[ratio.slower.key] or not records[ratio.faster.key]:
        return f"- **{ratio.slower.label} → {ratio.faster.label}**: {NOT_RUN}; {ratio.claim}"
    slower, faster, shared = on_shared_seeds(records[ratio.slower.key], records[ratio.faster.key])
    pair = f"**{ratio.slower.label} → {ratio.faster.label}**{shared}"
    if not slower:
        return f"- {pair}: no seed run by both; {ratio.claim}"
    point, low, high = bootstrap_ratio(fleet_rounds(slower), fleet_rounds(faster))
    bound = bound_mark(slower, faster)
    unit = _times(bound, bootstrap_ratio(unit_rounds(slower), unit_rounds(faster)))
    rig = _rig_ratio(slower, faster)
    on_rigs = "" if rig == "-" else f"; in time on the rigs, fleet / per unit: {rig}"
    return (
        f"- {pair}: fleet speed-up in rounds {bound}{point:.2f}× (95 % bootstrap {low:.2f}–{high:.2f}), "
        f"per unit {unit}{on_rigs}; {ratio.claim}"
    )


def unseen_summary(records: list[RunRecord]) -> tuple[str, str]:
    """Mean score and share of episodes held to the cap on unseen units, over every run of an arm."""
    scores = [s for r in records for s in r.unseen_scores()]
    if not scores:
        return "-", "-"
    cap = records[0].episode_cap
    held = sum(s >= cap for s in scores)
    return f"{sum(scores) / len(scores):.0f}", f"{100 * held / len(scores):.0f} % of {len(scores)}"


def _arms_table(plan: Plan, records: Records) -> str:
    rows = []
    for arm in plan.arms:
        done = records[arm.key]
        if not done:
            rows.append([arm.label, NOT_RUN, *["-"] * 9])
            continue
        complete = sum(c.complete for c in completions(done))
        walls = sorted(r.wall_seconds for r in done)
        mean_unseen, held = unseen_summary(done)
        rig = rig_minutes(done)
        rows.append(
            [
                arm.label,
                bootstrap_median(fleet_rounds(done)).format(),
                bootstrap_median(unit_rounds(done)).format(),
                "-" if rig is None else bootstrap_median(rig[0]).format(1),
                "-" if rig is None else bootstrap_median(rig[1]).format(1),
                controlled_minutes(done),
                f"{complete}/{len(done)}",
                _seeds(done),
                mean_unseen,
                held,
                f"{walls[len(walls) // 2]:.1f}",
            ]
        )
    header = [
        "arm",
        "rounds until the last unit completes: median (95 % CI)",
        "rounds per unit: median (95 % CI)",
        "time on the rigs until the last unit completes, min: median (95 % CI)",
        "time on the rigs per unit, min: median (95 % CI)",
        "time on the rigs until 50 / 90 / 100 % of the units complete, min: median",
        "runs complete within M",
        "seeds",
        "unseen units: mean score",
        "unseen units: held to the cap",
        "wall s (median)",
    ]
    return markdown_table(header, rows)


def transport_check_line(label: str, seed: int, local: RunRecord, mqtt: RunRecord) -> str:
    """Whether one seed gave the same scores over MQTT as over the in-process bus (runs made on different
    machines are not compared: a seed fixes a run on one machine only)."""
    head = f"- Transport check: seed {seed} of {label} over MQTT (embedded broker): "
    if local.host != mqtt.host:
        return (
            head + f"not compared: the in-process run was made on `{local.host}`, this one on `{mqtt.host}`."
        )
    return (
        head
        + f"scores {'identical' if local.scores() == mqtt.scores() else 'DIFFERENT'} to the in-process bus."
    )


def episode_lines(plan: Plan, records: Records) -> list[str]:
    """For each arm whose rounds hold several episodes (``paper-code``): its units complete and the
    episodes per unit to completion."""
    lines = []
    for arm in plan.arms:
        units = [u for r in records[arm.key] if (per := r.episodes_to_completion()) for u in per.values()]
        if not units:
            continue
        episodes = sorted(n for n, _ in units)
        done = sum(held for _, held in units)
        lines.append(
            f"- **{arm.label}**: {done} of {len(units)} units complete within M; episodes per unit to "
            f"completion: median {float(np.median(episodes)):.0f} (range {episodes[0]}–{episodes[-1]}"
            f"{'' if done == len(units) else '; an incomplete unit counts the episodes it played'})"
        )
    return [*lines, ""] if lines else []


def seed_range(seeds: Iterable[int]) -> str:
    """``100–109``, ``3``, or ``0, 2, 5`` if not consecutive."""
    listed = list(seeds)
    if len(listed) > 1 and listed == list(range(listed[0], listed[0] + len(listed))):
        return f"{listed[0]}–{listed[-1]}"
    return ", ".join(map(str, listed))


def _seeds(records: list[RunRecord]) -> str:
    return seed_range(int(r.result_settings["seed"]) for r in records)


def alone_arm(plan: Plan, arm: Arm) -> Arm | None:
    """The plan's arm "each unit alone" with ``arm``'s settings otherwise (None if none, or ``arm`` is it)."""
    if arm.settings["mode"] == "individual":
        return None
    for other in plan.arms:
        expected = {**arm.settings, "mode": "individual"}
        for federation_only in ("transport", "scheme", "scheme_params"):
            expected.pop(federation_only, None)
        if other.settings == expected:
            return other
    return None


def _speed_up_table(plan: Plan, records: Records) -> str:
    rows = []
    for arm in plan.arms:
        alone = alone_arm(plan, arm)
        if alone is None:
            continue
        slower, faster = records[alone.key], records[arm.key]
        if not slower or not faster:
            continue
        bound = bound_mark(slower, faster)
        fleet = bootstrap_ratio(fleet_rounds(slower), fleet_rounds(faster))
        unit = bootstrap_ratio(unit_rounds(slower), unit_rounds(faster))
        efficiency = f"{bound}{fleet[0] / arm.units:.2f}"
        rows.append(
            [
                arm.label,
                str(arm.units),
                _times(bound, fleet),
                _times(bound, unit),
                efficiency,
                _rig_ratio(slower, faster),
            ]
        )
    if not rows:
        return ""
    header = [
        "arm (vs each unit alone, same preset)",
        "N units",
        "speed-up, rounds until the last unit completes (95 % CI)",
        "speed-up, rounds per unit (95 % CI)",
        "efficiency (speed-up / N)",
        "speed-up, time on the rigs: fleet / per unit (95 % CI)",
    ]
    return markdown_table(header, rows)
