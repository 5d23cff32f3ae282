"""A run that does not fit the machine's memory is refused before anything starts, with one line saying what
fits and what to type instead; the available memory is given to the check (a fake machine's figure)."""

from pathlib import Path

import pytest

from fleetrl.cli.main import main
from fleetrl.runs.host_settings import units_per_core
from fleetrl.runs.memory_fit import (
    COMMAND_MB,
    FORKED_WORKER_MB,
    HEADROOM,
    RunLayout,
    available_mb,
    memory_problem,
)

GB = 1024.0


def problem(
    layout: RunLayout, available: float | None, *, hosts: bool = True, threads: bool = True
) -> str | None:
    return memory_problem(layout, available, threads_possible=threads, hosts_possible=hosts, cores=2)


def test_the_available_memory_is_read_from_meminfo_and_unknown_elsewhere(tmp_path: Path) -> None:
    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:       24683584 kB\nMemAvailable:    2097152 kB\n")
    assert available_mb(meminfo) == 2048.0
    meminfo.write_text("MemTotal:       24683584 kB\n")
    assert available_mb(meminfo) is None
    assert available_mb(tmp_path / "missing") is None


def test_a_run_that_fits_or_a_machine_that_says_nothing_is_not_refused() -> None:
    assert problem(RunLayout.of(8, "federated", "mqtt", 1, forked=True), 24 * GB) is None
    assert problem(RunLayout.of(10**6, "federated", "mqtt", 1, forked=False), None) is None


def test_a_hundred_spawned_worker_processes_are_refused_with_hosts_to_type_instead() -> None:
    layout = RunLayout.of(100, "federated", "mqtt", 1, forked=False)
    why = problem(layout, 24 * GB)
    assert why is not None and "\n" not in why
    assert why.startswith("--units 100: 100 worker processes of ~")
    assert "24.0 GB available" in why
    hosts = RunLayout.of(100, "federated", "mqtt", 50, forked=False).estimate_mb() / GB
    assert why.endswith(f"type --units-per-host 50 (about {hosts:.1f} GB) instead")  # 2 cores, processes
    most = int(why.split("at most ")[1].split(" units")[0])
    budget = 24 * GB * (1 - HEADROOM)
    assert RunLayout.of(most, "federated", "mqtt", 1, forked=False).estimate_mb() <= budget
    assert RunLayout.of(most + 1, "federated", "mqtt", 1, forked=False).estimate_mb() > budget


def test_without_hosts_the_advice_is_threads_and_alone_it_is_fewer_units() -> None:
    processes = RunLayout.of(100, "federated", "mqtt", 1, forked=False)
    assert "type --transport local (worker threads" in str(problem(processes, 24 * GB, hosts=False))
    alone = RunLayout.of(100, "individual", "mqtt", 1, forked=False)
    why = str(problem(alone, 24 * GB, hosts=False, threads=False))
    most = int(why.split("at most ")[1].split(" units")[0])
    assert why.endswith(f"type --units {most} instead") and 0 < most < 100


def test_a_fleet_too_large_even_for_hosts_is_told_the_most_units_hosts_hold() -> None:
    layout = RunLayout.of(10**6, "federated", "local", 1000, forked=True)
    why = str(problem(layout, 4 * GB))
    most = int(why.rsplit("--units ", 1)[1].split()[0])
    assert f"--units {most} --units-per-host {units_per_core(most, 2)} instead" in why
    assert 0 < most < 10**6


def test_unit_hosts_as_processes_cost_a_worker_process_each_beside_their_units() -> None:
    threads = RunLayout.of(1000, "federated", "local", 500, forked=True)
    processes = RunLayout.of(1000, "federated", "mqtt", 500, forked=True)
    assert processes.hosts == threads.hosts == 2
    assert processes.estimate_mb() - threads.estimate_mb() == 2 * FORKED_WORKER_MB
    assert processes.described() == "2 unit hosts of 500 units (processes)"
    flat = RunLayout.of(1000, "federated", "mqtt", 1, forked=True)
    assert flat.estimate_mb() > 50 * processes.estimate_mb()


def test_a_machine_without_room_for_the_command_itself_says_so() -> None:
    why = str(problem(RunLayout.of(3, "federated", "local", 1, forked=True), COMMAND_MB / 2))
    assert why.endswith("type a machine with more memory instead") and "at most 0 units" in why


@pytest.mark.skipif(available_mb() is None, reason="no MemAvailable on this system: the check is skipped")
def test_train_refuses_a_fleet_larger_than_the_machine_before_creating_anything(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    argv = ["train", "--env", "cartpole", "--units", "100000", "--transport", "mqtt", "--out", str(out)]
    assert main([*argv, "--units-per-host", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--units 100000: 100000 worker processes" in err
    assert "--units-per-host" in err.split("type ")[1]  # pergrad, the default scheme, allows hosts
    assert main(argv) == 2  # by default hosts (about one per core), which do not fit 100000 units either
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "unit hosts of" in err and "(processes)" in err
    assert not out.exists()
