"""What each arm cost the machine: wall time per round and unit-steps per second, from records
(hand-computed)."""

from typing import Any

from fleetrl_lab.records import RunRecord
from fleetrl_lab.throughput import run_throughput, throughput_lines


def record(
    wall: float, steps: dict[str, list[int]], host: str = "AMD EPYC, AVX2, 2 cores", **w: Any
) -> RunRecord:
    workers = {k: {"score": [float(n) for n in s], "steps": s, **w} for k, s in steps.items()}
    return RunRecord({"workers": workers, "wall_seconds": wall, "host": host})


def test_a_run_s_seconds_per_round_and_unit_steps_per_second() -> None:
    # 2 units, 4 rounds (unit 1 left after 3), 100 + 60 steps in 8 s: 2 s a round, 20 unit-steps a second
    run = run_throughput(record(8.0, {"0": [10, 20, 30, 40], "1": [20, 20, 20]}))
    assert run is not None
    assert (run.units, run.rounds, run.seconds_per_round, run.unit_steps_per_second) == (2, 4, 2.0, 20.0)
    # rounds of several episodes whose steps were not kept
    several = RunRecord({"workers": {"0": {"score": [5.0, 15.0], "episodes": [2, 2]}}, "wall_seconds": 4.0})
    assert run_throughput(several) is None
    assert run_throughput(record(0.0, {"0": [5]})) is None


def test_the_table_gives_each_arm_s_medians_and_machines() -> None:
    fast = record(2.0, {"0": [100, 100]})  # 1 s a round, 100 unit-steps/s
    slow = record(8.0, {"0": [100, 100, 100, 100]}, host="Intel(R) Xeon(R) Processor, AVX-512, 2 cores")
    middle = record(3.0, {"0": [90, 90, 120]})  # 1 s a round, 100 unit-steps/s
    lines = throughput_lines([("one unit", [fast, slow, middle]), ("not run", [])])
    rows = [line for line in lines if line.startswith("| one unit")]
    assert len(rows) == 1 and not any("not run" in line for line in lines)
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    # rounds 2, 4, 3 → 3; s per round 1, 2, 1 → 1; unit-steps/s 100, 50, 100 → 100
    assert cells == ["one unit", "1", "3", "1.00", "100", "3", "AMD EPYC; Intel(R) Xeon(R) Processor"]
    assert throughput_lines([("not run", [])]) == []
