"""What `fleetrl train` prints when a run ends about its time on the rigs, from a summary (hand-made)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleetrl.cli.main import print_summary

RIG = {
    "period": 0.02,
    "rule": "nobody waits",
    "fleet": 90.0,
    "per_unit": {"0": 20.0, "1": 50.0, "2": 50.0, "3": 90.0},
    "complete": False,
}
WORKERS = {
    w: {"completed_at_round": None if w == "3" else 5, "final_wma": 100.0, "state": "stopped"}
    for w in RIG["per_unit"]
}


def _printed(rig: dict[str, object], capsys: pytest.CaptureFixture[str]) -> list[str]:
    print_summary({"wall_seconds": 1.0, "rounds": 5, "workers": WORKERS, "rig_seconds": rig}, Path("run"))
    return [line for line in capsys.readouterr().out.splitlines() if "rigs" in line or "controlled" in line]


def test_the_end_of_a_run_gives_the_time_until_50_90_and_100_percent_of_the_units_were_controlled(
    capsys: pytest.CaptureFixture[str],
) -> None:
    controlled = {"50": 50.0, "90": None, "100": None}
    assert _printed({**RIG, "controlled": controlled}, capsys) == [
        "  time on real-time rigs (nobody waits, 20 ms a step): at least 90.0 s until the last unit "
        "completed, median 50.0 s per unit",
        "    until 50 / 90 / 100 % of the units were controlled: 50.0 s / not reached / not reached",
    ]
    complete = {"50": 20.0, "90": 90.0, "100": 90.0}
    assert _printed({**RIG, "complete": True, "controlled": complete}, capsys)[1] == (
        "    until 50 / 90 / 100 % of the units were controlled: 20.0 s / 90.0 s / 90.0 s"
    )


def test_a_summary_written_before_the_shares_were_kept_prints_without_them(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert len(_printed(RIG, capsys)) == 1
