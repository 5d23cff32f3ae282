"""`fleetrl experiment all --quick`: every experiment's pipeline end to end (files, numbers that parse);
the science is not asserted here (see docs/results.md for full runs)."""

import csv
import json
import re
import shutil
from pathlib import Path

import pytest

from fleetrl.cli.main import main
from fleetrl.experiments.catalog import EXPERIMENTS, PLANS

pytestmark = [pytest.mark.slow, pytest.mark.mqtt]  # sweeps of real training runs, one arm over MQTT


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("experiments")
    assert main(["experiment", "all", "--seeds", "1", "--quick", "--out", str(out)]) == 0
    return out


@pytest.mark.timeout(600)
def test_report_has_every_section_with_its_command_and_seeds(quick_report: Path) -> None:
    report = (quick_report / "report.md").read_text()
    assert report.count("Command: `fleetrl experiment ") == len(EXPERIMENTS)
    for name in EXPERIMENTS:
        assert f"fleetrl experiment {name} --seeds 1 --first-seed 100" in report
    seeds = "Seeds: tuning seeds 0–9 on fleet seed 0; the figures below are on seed 100 (fleet seed 0), never"
    assert report.count(seeds) == len(EXPERIMENTS)
    for image in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report):
        assert (quick_report / image).stat().st_size > 5_000


@pytest.mark.parametrize("name", sorted(PLANS))
def test_training_experiments_write_parseable_runs(quick_report: Path, name: str) -> None:
    rows = list(csv.DictReader((quick_report / name / "runs.csv").open()))
    assert rows, name
    for row in rows:
        assert int(row["fleet_rounds"]) >= 1 and float(row["wall_seconds"]) > 0
        assert all(int(r) >= 1 for r in row["worker_rounds"].split(";"))
    section = (quick_report / name / "section.md").read_text()
    assert re.findall(r"speed-up (?:≥ |≤ |~)?(\d+\.\d+)×", section)
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
    from fleetrl.experiments.runner import publish_report

    published = publish_report(quick_report, tmp_path / "docs" / "results.md")
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", published.read_text())
    assert images and all((published.parent / image).is_file() for image in images)


def test_table2_and_peers_write_their_numbers(quick_report: Path) -> None:
    matrix = list(csv.reader((quick_report / "table2" / "seed-100" / "motor_correlation.csv").open()))
    assert any(float(cell) == pytest.approx(1.0) for cell in matrix[1][1:])
    results = [
        json.loads(p.read_text()) for p in (quick_report / "records" / "peers" / "cartpole").glob("*.json")
    ]
    assert len(results) == 1 and all(r["episodes"] >= 1 for r in results)  # --seeds 1: unit 100 mod 3
    section = (quick_report / "peers" / "section.md").read_text()
    assert "SB3 PPO (defaults)" in section and re.findall(r"\| (?:≤ )?\d+\.\d+× \(", section)
