"""The benchmark scripts that drive the chief and workers directly (not through the command line) still run:
a product change to the machines' constructors shows here, not when someone next wants the figure."""

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def run_script(name: str, *args: str) -> str:
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / name), *args], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.mark.slow
def test_round_overhead_measures_rounds_on_the_in_process_bus() -> None:
    out = run_script("round_overhead.py", "--quick", "--transports", "local")
    rows = [line for line in out.splitlines() if line.startswith("| local |")]
    assert [row.split("|")[2].strip() for row in rows] == ["3", "8"]


@pytest.mark.slow
@pytest.mark.mqtt
@pytest.mark.mosquitto
def test_wire_cost_times_a_round_of_each_scheme_through_mosquitto() -> None:
    out = run_script("wire_cost.py", "--rounds", "3", "--workers", "2")
    rows = {
        line.split()[0]: line.split()
        for line in out.splitlines()
        if line.split()[:1] in (["fedavg"], ["pergrad"])
    }
    assert set(rows) == {"fedavg", "pergrad"}
    assert rows["pergrad"][2] != "1" and float(rows["pergrad"][3]) > 0
