"""The Table 2 report section pools several fleets, as the paper's ranges are judged (docs/devices.md)."""

import re
from pathlib import Path

import pytest

from fleetrl.devices.homogeneity import pooled_homogeneity
from fleetrl_lab.sections import TABLE2_FLEETS, paper_range_verdict, table2_section


def test_the_section_pools_three_fleets_and_agrees_with_pooled_homogeneity(tmp_path: Path) -> None:
    section = table2_section(tmp_path / "table2", [100, 101], ["preamble line"], fleet_seed=4)
    pooled = pooled_homogeneity(range(4, 4 + TABLE2_FLEETS), [100, 101])
    rows = re.findall(r"^\| (\S+) \| ([\d.]+) .*\| ([\d.]+) .*\|$", section, re.MULTILINE)
    assert [fleet for fleet, _, _ in rows] == ["4", "5", "6"]
    pooled_row = re.search(
        r"^\| \*\*pooled\*\* \| \*\*([\d.]+)\*\* .*\| \*\*([\d.]+)\*\* .*\|$", section, re.M
    )
    assert pooled_row is not None
    assert float(pooled_row[1]) == pytest.approx(pooled.motor_median, abs=5e-4)
    assert float(pooled_row[2]) == pytest.approx(pooled.pendulum_median, abs=5e-4)
    assert f"{len(pooled.motor)} off-diagonal pairs" in section
    assert "preamble line" in section
    for fleet in (4, 5, 6):
        assert (tmp_path / "table2" / f"fleet-{fleet}" / "seed-101" / "pendulum_correlation.csv").is_file()


@pytest.mark.parametrize(
    ("median", "words"),
    [(0.80, "inside"), (0.75, "inside"), (0.86, "inside"), (0.749, "outside"), (0.9, "outside")],
)
def test_the_verdict_names_the_paper_range(median: float, words: str) -> None:
    assert paper_range_verdict(median, (0.75, 0.86)) == f"{words} the paper's 0.75–0.86"
