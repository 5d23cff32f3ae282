"""Where a unit's time on the rigs goes: its rounds split at its first long episode (learning to hold the
task before, holding it until its criterion does after), on its own episodes and resets back to back."""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from fleetrl.envs.catalog import describe_env, get_env_spec
from fleetrl.runs.rig_time import reset_seconds
from fleetrl_lab.records import RunRecord

LONG_SHARE = 0.4
"""an episode at least this share of the episode cap is a long one"""


@dataclass(frozen=True)
class UnitPhases:
    """One unit's rounds and own minutes on a rig before its first long episode and from it to completion."""

    rounds_before: int
    rounds_after: int
    minutes_before: float
    minutes_after: float


def unit_phases(
    steps: Sequence[int], completed_at: int | None, cap: int, period: float, reset: float = 0.0
) -> UnitPhases | None:
    """Split one unit's rounds (each round's steps, each after a ``reset`` of seconds), up to the round its
    criterion held, at its first long episode; None if no episode was long."""
    played = list(steps if completed_at is None else steps[:completed_at])
    first = next((i for i, n in enumerate(played) if n >= LONG_SHARE * cap), None)
    if first is None:
        return None
    before, after = played[:first], played[first:]
    return UnitPhases(
        len(before),
        len(after),
        (sum(before) * period + len(before) * reset) / 60,
        (sum(after) * period + len(after) * reset) / 60,
    )


def run_phases(record: RunRecord) -> list[UnitPhases]:
    """Every unit's phases in one run (units without a long episode left out)."""
    settings = record.result_settings
    env = str(settings["env"])
    period = get_env_spec(env).control_period
    cap = describe_env(env).episode_cap
    if period is None or cap is None:
        return []
    phases = []
    fleet_seed, profile = int(settings.get("fleet_seed") or 0), settings.get("fleet_profile")
    for key, worker in record.data["workers"].items():
        if "steps" not in worker:  # rounds of several episodes, no steps kept
            continue
        steps = worker["steps"]
        reset = reset_seconds(env, int(key), fleet_seed, profile)
        split = unit_phases(steps, worker.get("completed_at_round"), cap, period, reset)
        if split is not None:
            phases.append(split)
    return phases


def phases_table(arms: Sequence[tuple[str, Sequence[RunRecord]]]) -> str:
    """Per arm, the medians over its units of :class:`UnitPhases` and the share of time after the first long
    episode, as a markdown table (empty if no arm has any)."""
    rows = []
    for label, records in arms:
        units = [p for record in records for p in run_phases(record)]
        if not units:
            continue
        after = statistics.median(p.minutes_after for p in units)
        before = statistics.median(p.minutes_before for p in units)
        share = statistics.median(p.minutes_after / (p.minutes_before + p.minutes_after) for p in units)
        rows.append(
            f"| {label} | {len(units)} | {statistics.median(p.rounds_before for p in units):g} | "
            f"{statistics.median(p.rounds_after for p in units):g} | {before:.1f} | {after:.1f} | "
            f"{share:.0%} |"
        )
    if not rows:
        return ""
    header = (
        f"| arm | units | rounds before the first long episode (≥ {LONG_SHARE:.0%} of the cap) "
        "| rounds from it until the criterion held | own minutes on the rig before "
        "| own minutes from it | share of the time from it |\n|---|---|---|---|---|---|---|"
    )
    return "\n".join([header, *rows])


def phases_lines(arms: Sequence[tuple[str, Sequence[RunRecord]]]) -> list[str]:
    """The report's lines on where the time on the rigs goes (none if no arm has a long episode)."""
    table = phases_table(arms)
    if not table:
        return []
    note = (
        "Where each unit's own time on the rig goes (its episodes and their resets back to back, up to "
        f"the round its criterion held): before its first long episode (≥ {LONG_SHARE:.0%} of the cap) it "
        "learns to hold the task in short episodes; from it on it plays long ones until the "
        "criterion (the WMA of its last 10 scores) holds. Medians over every unit of the arm's "
        "runs (`fleetrl_lab.rig_phases`)."
    )
    return ["", note, "", table]
