"""The report is computed from the run records alone: no run directory is read, the same records give the
same text, and it states the tuning and the reported seed sets."""

import re
from pathlib import Path

from experiment_fakes import record, write_record_of

from fleetrl_lab.arms import Places, arm
from fleetrl_lab.plan import Plan, Ratio, run_plan
from fleetrl_lab.runner import seeds_line

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
    assert "| 3/3 | 100–102 | 310 | 50 % of 6 | 30.0 |" in rows["| each unit alone"]
    assert rows["| fedavg"].startswith("| fedavg | 20 (10–25) | 19 (")
    # 4 unseen episodes × 3 seeds, cap 500
    assert "| 3/3 | 100–102 | 350 | 50 % of 12 | 9.0 |" in rows["| fedavg"]
    speed_up = next(line for line in section.splitlines() if line.startswith("| fedavg | 3 |"))
    assert (
        speed_up.startswith("| fedavg | 3 | 2.00× (") and "| 2.05× (" in speed_up and "| 0.67 | " in speed_up
    )
    # time on the rigs, fleet / per unit: the fake rounds' steps are their scores (1, 2, … until completion)
    assert re.search(r"\| 0\.67 \| [\d.]+× \([\d.]+–[\d.]+\) / [\d.]+× \([\d.]+–[\d.]+\) \|$", speed_up)
    ratio = next(line for line in section.splitlines() if line.startswith("- **each unit alone → fedavg**"))
    assert ratio.startswith("- **each unit alone → fedavg**: fleet speed-up in rounds 2.00× (95 % bootstrap")
    rig_ratio = re.search(r"\| ([^|]+) \|$", speed_up)
    assert rig_ratio is not None  # the speed-up table's time on the rigs, said again beside the rounds
    assert f"in time on the rigs, fleet / per unit: {rig_ratio.group(1)}; the claim" in ratio
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


def test_other_arms_run_on_fewer_seeds_and_the_report_says_so(tmp_path: Path) -> None:
    places = Places(tmp_path / "runs", tmp_path / "committed")
    write_records(places)
    ratios = [Ratio(ALONE, FEDAVG, "the claim")]
    plan = Plan("demo", "A demo", [ALONE, FEDAVG], 100, ratios, headline=[FEDAVG])
    assert plan.seeds_of(FEDAVG, SEEDS, 1) == SEEDS and plan.seeds_of(ALONE, SEEDS, 1) == [100]
    assert plan.seeds_of(ALONE, SEEDS, None) == SEEDS
    line = seeds_line(SEEDS, 0, 1)
    assert line.endswith("; arms other than the headline arms on seeds 100, never used while tuning.")
    section = run_plan(plan, tmp_path / "out", places, SEEDS, [line, ""], other_seeds=1)
    assert "| each unit alone | 30 (30–30) | 29 (" in section and "| 1/1 | 100 |" in section
    assert "| fedavg | 20 (10–25) |" in section and "| 3/3 | 100–102 |" in section
    csv_rows = (tmp_path / "out" / "demo" / "runs.csv").read_text().splitlines()
    assert [row.split(",")[1] for row in csv_rows[1:]] == ["100", "100", "101", "102"]


def test_a_headline_plan_keeps_the_headline_arms_and_their_comparisons_only() -> None:
    pergrad = arm("cartpole", 3, "federated", "standard", 100, "pergrad", "pergrad")
    ratios = [Ratio(ALONE, FEDAVG, "a"), Ratio(ALONE, pergrad, "b"), Ratio(FEDAVG, pergrad, "c")]
    plan = Plan("demo", "A demo", [ALONE, FEDAVG, pergrad], 100, ratios, (ALONE, pergrad), pergrad,
                headline=[ALONE, FEDAVG])  # fmt: skip
    cut = plan.headline_only()
    assert cut.name == "demo-headline" and cut.arms == [ALONE, FEDAVG]
    assert [r.claim for r in cut.ratios] == ["a"]
    assert cut.side_by_side is None and cut.mqtt_check is None


def test_a_sweep_runs_seed_by_seed_across_the_arms(tmp_path: Path) -> None:
    from fleetrl_lab.plan import _seed_major

    places = Places(tmp_path / "runs", tmp_path / "committed")
    order = _seed_major([ALONE.runs(places, SEEDS), FEDAVG.runs(places, SEEDS[:2])])
    assert [(run.labels["arm"], run.labels["seed"]) for run in order] == [
        (ALONE.key, 100), (FEDAVG.key, 100), (ALONE.key, 101), (FEDAVG.key, 101), (ALONE.key, 102),
    ]  # fmt: skip


def test_a_report_from_the_records_alone_runs_nothing_and_names_what_is_missing(tmp_path: Path) -> None:
    places = Places(tmp_path / "runs", tmp_path / "committed")
    for seed, fed in zip(SEEDS[:2], (10, 20), strict=True):  # fedavg has 2 of 3 seeds, alone none
        write_record_of(FEDAVG.run(places, seed), record(FEDAVG.run(places, seed), fed))
    paper = arm("cartpole", 3, "federated", "standard", 100, "paper", "paper")
    plan = Plan("demo", "A demo", [ALONE, FEDAVG, paper], 100, [Ratio(ALONE, FEDAVG, "the claim")])
    section = run_plan(plan, tmp_path / "out", places, SEEDS, [seeds_line(SEEDS, 0), ""], run=False)
    assert not places.runs.exists()  # nothing was started
    assert "| each unit alone | not run yet | - |" in section
    table = next(part for part in section.split("\n\n") if part.startswith("| arm |")).splitlines()
    # the arms' table: a cell for each column, run or not
    assert table[0].startswith("| arm |") and "until 50 / 90 / 100 % of the units complete" in table[0]
    assert {line.count(" | ") for line in table[2:]} == {table[0].count(" | ")}
    assert "| fedavg | 15 (10–20) |" in section and "| 0/2 | 100–101 |" not in section
    assert "| 2/2 | 100–101 |" in section
    assert "- **each unit alone → fedavg**: not run yet; the claim" in section
    assert "| fedavg | 3 |" not in section  # no speed-up without the arm it is measured against


def test_the_transport_check_compares_runs_of_one_machine_only(tmp_path: Path) -> None:
    from fleetrl_lab.plan import transport_check_line
    from fleetrl_lab.records import RunRecord

    fed = arm("qube", 3, "federated", "standard", 20, "fed", "pergrad")
    data = record(fed.run(Places(tmp_path / "runs", tmp_path / "records"), 100), fleet=12)
    other_scores = {
        **data,
        "workers": {**data["workers"], "0": {**data["workers"]["0"], "score": [9.0] * 12}},
    }
    line = transport_check_line("fed", 100, RunRecord(data), RunRecord(data))
    assert line.endswith("scores identical to the in-process bus.")
    line = transport_check_line("fed", 100, RunRecord(data), RunRecord(other_scores))
    assert line.endswith("scores DIFFERENT to the in-process bus.")
    elsewhere = RunRecord({**data, "host": "another CPU"})
    line = transport_check_line("fed", 100, RunRecord(data), elsewhere)
    assert "not compared: the in-process run was made on `test host`, this one on `another CPU`" in line
