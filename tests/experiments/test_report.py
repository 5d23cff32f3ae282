"""The report is computed from the run records alone: no run directory is read, the same records give the
same text, and it states the tuning and the reported seed sets."""

from pathlib import Path

from experiment_fakes import record, write_record_of

from fleetrl.experiments.arms import Places
from fleetrl.experiments.catalog import arm
from fleetrl.experiments.plan import Plan, Ratio, run_plan
from fleetrl.experiments.runner import seeds_line

SEEDS = [100, 101, 102]
ALONE = arm("cartpole", 3, "individual", "standard", 100, "each unit alone")
FEDAVG = arm("cartpole", 3, "federated", "standard", 100, "fedavg", "fedavg")
PLAN = Plan("demo", "A demo", [ALONE, FEDAVG], 100, [Ratio(ALONE, FEDAVG, "the claim")])


def write_records(places: Places) -> None:
    for seed, alone, fed in zip(SEEDS, (30, 40, 50), (10, 20, 25), strict=True):
        write_record_of(ALONE.run(places, seed), record(ALONE.run(places, seed), alone, wall=30.0))
        unseen = [500.0, 500.0, 100.0, 300.0]
        write_record_of(
            FEDAVG.run(places, seed), record(FEDAVG.run(places, seed), fed, wall=9.0, unseen=unseen)
        )


def test_a_section_from_records_alone_shows_medians_speed_ups_and_the_unseen_units(tmp_path: Path) -> None:
    places = Places(tmp_path / "runs", tmp_path / "committed")
    write_records(places)
    section = run_plan(PLAN, tmp_path / "out", places, SEEDS, [seeds_line(SEEDS, 0), ""])
    assert not places.runs.exists()  # nothing ran, no run directory was needed
    rows: dict[str, str] = {}
    for line in section.splitlines():  # the first table's row of each arm
        rows.setdefault(line.split(" | ")[0], line)
    # fleet rounds: alone 30/40/50, fedavg 10/20/25; per unit k completes at fleet - k
    assert rows["| each unit alone"].startswith("| each unit alone | 40 (30–50) | 39 (")
    assert "| 3/3 | 310 | 50 % of 6 | 30.0 |" in rows["| each unit alone"]
    assert rows["| fedavg"].startswith("| fedavg | 20 (10–25) | 19 (")
    assert "| 3/3 | 350 | 50 % of 12 | 9.0 |" in rows["| fedavg"]  # 4 unseen episodes × 3 seeds, cap 500
    speed_up = next(line for line in section.splitlines() if line.startswith("| fedavg | 3 |"))
    assert (
        speed_up.startswith("| fedavg | 3 | 2.00× (")
        and "| 2.05× (" in speed_up
        and speed_up.endswith("| 0.67 |")
    )
    assert "- **each unit alone → fedavg**: fleet speed-up 2.00× (95 % bootstrap" in section
    assert "seeds 100–102 (fleet seed 0), never used while tuning" in section
    assert "Runs made on: `test host`." in section
    assert (tmp_path / "out" / "demo" / "mean_score.png").stat().st_size > 5_000

    again = run_plan(PLAN, tmp_path / "again", places, SEEDS, [seeds_line(SEEDS, 0), ""])
    assert again == section.replace(str(tmp_path / "out"), str(tmp_path / "again"))


def test_the_report_states_both_seed_sets_and_warns_when_they_overlap() -> None:
    assert seeds_line(list(range(100, 110)), 0) == (
        "Seeds: tuning seeds 0–9 on fleet seed 0; the figures below are on seeds 100–109 (fleet seed 0),"
        " never used while tuning."
    )
    assert "WARNING: seed(s) 8–9 are tuning seeds" in seeds_line(list(range(8, 12)), 1)
