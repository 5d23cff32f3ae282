"""`fleetrl experiment … --quick`: the pipeline end to end (files, numbers that parse) on one training plan
(fig5: ratios, the speed-up table, the side-by-side plot, the MQTT check), Table 2 and the SB3 peers; every
other plan runs the same code (`run_plan`), and its arms are checked to be valid settings without running
them. The science is not asserted here (see docs/results.md for full runs)."""

import csv
import json
import re
import shutil
from pathlib import Path

import pytest

from fleetrl.cli.main import main
from fleetrl.runs.setting_values import build
from fleetrl.runs.settings import RunSettings
from fleetrl_lab.arms import FULL, QUICK
from fleetrl_lab.catalog import PLANS

# real training sweeps, one arm over MQTT; the module fixture that runs them needs more than 300 s
pytestmark = [pytest.mark.slow, pytest.mark.mqtt, pytest.mark.timeout(900)]
RUN = ("fig5", "table2", "peers")
"""the experiments run end to end here"""


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("experiments")
    for name in RUN:
        assert main(["experiment", name, "--seeds", "1", "--quick", "--out", str(out)]) == 0
    return out


@pytest.mark.timeout(900)
def test_report_has_every_section_with_its_command_and_seeds(quick_report: Path) -> None:
    report = (quick_report / "report.md").read_text()
    assert report.count("Command: `fleetrl experiment ") == len(RUN)
    for name in RUN:
        assert f"fleetrl experiment {name} --seeds 1 --first-seed 100" in report
    seeds = "Seeds: tuning seeds 0–9 on fleet seed 0; the figures below are on seed 100 (fleet seed 0), never"
    assert report.count(seeds) == len(RUN)
    for image in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report):
        assert (quick_report / image).stat().st_size > 5_000


@pytest.mark.parametrize("name", sorted(PLANS))
@pytest.mark.parametrize("budget", [QUICK, FULL], ids=["quick", "full"])
def test_every_plan_is_made_of_valid_runs(name: str, budget: object, tmp_path: Path) -> None:
    plan = PLANS[name](budget)  # type: ignore[arg-type]
    assert plan.arms and len({arm.key for arm in plan.arms}) == len(plan.arms)
    for arm in plan.arms:
        build(RunSettings, {}, {"out": tmp_path, **arm.settings})  # resolved: every setting checked


def test_a_training_experiment_writes_parseable_runs(quick_report: Path) -> None:
    name = "fig5"
    rows = list(csv.DictReader((quick_report / name / "runs.csv").open()))
    assert rows, name
    for row in rows:
        assert int(row["fleet_rounds"]) >= 1 and float(row["wall_seconds"]) > 0
        assert all(int(r) >= 1 for r in row["worker_rounds"].split(";"))
    section = (quick_report / name / "section.md").read_text()
    assert re.findall(r"speed-up in rounds (?:≥ |≤ |~)?(\d+\.\d+)×", section)
    if "Transport check" in section:
        assert "scores identical to the in-process bus" in section


def test_every_run_left_a_record_and_the_report_regenerates_from_records_alone(quick_report: Path) -> None:
    records = sorted((quick_report / "records").glob("*/seed-100.json"))
    assert len(records) == len(list((quick_report / "runs").glob("*/seed-100")))
    for path in records:
        record = json.loads(path.read_text())
        assert record["result_settings"]["seed"] == 100 and record["wall_seconds"] > 0
        unseen = record["generalisation"]
        assert unseen["units"] == [10, 11] and all(len(s) == 2 for s in unseen["scores"].values())
    before = (quick_report / "fig5" / "section.md").read_text()
    shutil.rmtree(quick_report / "runs" / "qube-3-federated-standard-m4-fedavg")
    assert main(["experiment", "fig5", "--seeds", "1", "--quick", "--out", str(quick_report)]) == 0
    assert not (quick_report / "runs" / "qube-3-federated-standard-m4-fedavg").exists()  # nothing ran again
    assert (quick_report / "fig5" / "section.md").read_text() == before


def test_published_report_carries_its_images(quick_report: Path, tmp_path: Path) -> None:
    from fleetrl_lab.runner import publish_report

    published = publish_report(quick_report, tmp_path / "docs" / "results.md")
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", published.read_text())
    assert images and all((published.parent / image).is_file() for image in images)


def test_table2_and_peers_write_their_numbers(quick_report: Path) -> None:
    matrix = list(
        csv.reader((quick_report / "table2" / "fleet-0" / "seed-100" / "motor_correlation.csv").open())
    )
    assert any(float(cell) == pytest.approx(1.0) for cell in matrix[1][1:])
    results = [
        json.loads(p.read_text()) for p in (quick_report / "records" / "peers" / "cartpole").glob("*.json")
    ]
    assert len(results) == 1 and all(r["episodes"] >= 1 for r in results)  # --seeds 1: unit 100 mod 3
    assert all(r["host"] for r in results)  # the machine it ran on, as a training record names it
    assert not list((quick_report / "records").rglob("*.log"))  # process output stays with the runs
    assert (quick_report / "runs" / "peers" / "cartpole" / "unit-1-seed-100.log").is_file()
    section = (quick_report / "peers" / "section.md").read_text()
    assert "Runs made on: `" in section and "not recorded" not in section
    assert "SB3 PPO (defaults)" in section and re.findall(r"\| (?:≤ )?\d+\.\d+× \(", section)
    # the regenerate command is the first seed's own unit run, writing the record the table read
    assert re.search(r"--unit 1 --seed 100 .*/peers/cartpole/unit-1-seed-100\.json", section)
