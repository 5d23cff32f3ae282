"""An uneven simulated fleet end to end: ``fleetrl train`` with a slow unit, a slow link, real-time pacing,
absences and a stalling unit finishes, records its settings, and — with the fully synchronous rule
(``--quorum 1``) — learns exactly what the even fleet learns (the conditions change when things happen, never
what is computed)."""

from __future__ import annotations

import csv
import json
from itertools import islice
from pathlib import Path

import pytest
from cli_helpers import Fleetrl

from fleetrl.runs.uneven import absences

pytestmark = pytest.mark.slow
RUN = ["train", "--env", "cartpole", "--units", "3", "--transport", "local"]
UNEVEN = ["--slow", "w2=2", "--absent", "0.3", "--absent-rounds", "1", "--pace", "0.1"]
UNEVEN += ["--link-delay", "w1=0.02", "--stall", "w1=0.5"]  # w1's link both slow and stalling


def scores(out: Path) -> list[tuple[str, str, str]]:
    with (out / "metrics.csv").open(newline="") as f:
        return sorted((r["worker"], r["round"], r["score"]) for r in csv.DictReader(f))


@pytest.mark.parametrize("scheme", ["fedavg", "pergrad"])  # once a round; at every step of the update
def test_an_uneven_fleet_finishes_and_learns_what_the_even_fleet_learns(
    tmp_path: Path, fleetrl: Fleetrl, scheme: str
) -> None:
    # seed 0's schedule has a unit away before round 2 or 3: the run below meets an absence
    assert any(any(islice(absences(0.3, 1.0, 0, worker), 2)) for worker in range(3))
    even, uneven = tmp_path / "even", tmp_path / "uneven"
    for out, extra in ((even, []), (uneven, UNEVEN)):
        argv = [*RUN, "--scheme", scheme, "--quorum", "1", "--max-rounds", "3", "--no-live"]
        argv += ["--out", str(out), *extra]
        done = fleetrl(*argv, timeout=240)
        assert done.returncode == 0, done.stderr
    summary = json.loads((uneven / "summary.json").read_text())
    assert summary["rounds"] == 3 and not summary["interrupted"]
    assert "error" not in summary["chief"]
    config = json.loads((uneven / "config.json").read_text())
    assert config["slow"] == {"w2": 2.0} and config["link_delay"] == {"w1": 0.02}
    assert config["absent"] == 0.3 and config["pace"] == 0.1 and config["stall"] == {"w1": 0.5}
    assert len(scores(uneven)) == 9 and scores(uneven) == scores(even)
