"""Time on the rigs, on hand-made timelines (one accounting: play, resets, absences, waits for the fleet)."""

from __future__ import annotations

import pytest

from fleetrl.devices.cartpole import CartPoleParams
from fleetrl.devices.qube.params import QubeConfig
from fleetrl.envs.catalog import get_env_spec
from fleetrl.runs.rig_time import (
    NO_BARRIER,
    UnitPlay,
    Waits,
    reset_seconds,
    rig_time,
    run_units,
    units_for,
    waits_of,
)
from fleetrl.runs.uneven import absences

EVERYONE = Waits(barrier=True)
"""a round barrier that waits for every unit (quorum 1)"""


def test_a_unit_alone_plays_and_resets_back_to_back() -> None:
    t = rig_time({"a": UnitPlay([10, 20, 30], completed_at=2, reset=1.0)}, 0.5, NO_BARRIER)
    # rounds 1 and 2: (10 + 20) steps of 0.5 s and two resets of 1 s; round 3 is after its criterion held
    assert t.fleet == t.per_unit["a"] == 17.0 and t.complete
    assert (t.clocks["a"].played, t.clocks["a"].reset, t.clocks["a"].waited) == (15.0, 2.0, 0.0)


def test_a_barrier_fleet_waits_for_its_straggler_whose_episode_overlaps_the_rounds_it_missed() -> None:
    """Unit s contributes to rounds 1 and 4 only: its second episode starts when round 1 closes (30) and
    ends at 80, after a's rounds 2 and 3 (40, 50); round 4 closes when s is ready."""
    units = {"a": UnitPlay([10, 10, 10, 10], 4), "s": UnitPlay({1: 30, 4: 50}, 4)}
    t = rig_time(units, 1.0, EVERYONE)
    assert t.fleet == 80 and t.per_unit == {"a": 80, "s": 80}
    assert (t.clocks["a"].played, t.clocks["a"].waited) == (40, 40)  # 20 in round 1, 20 in round 4
    assert (t.clocks["s"].played, t.clocks["s"].waited) == (80, 0)


def test_a_quorum_round_without_a_unit_closes_at_its_deadline_and_the_absent_unit_s_clock_runs() -> None:
    """pergrad, quorum 0.6 of 3 (2 units): c is absent before its second round for 1 round's worth of its
    own time (12 s), so round 2 closes without it at the deadline: a and b ready at 30, the round opened at
    20, a grace of 0.25 × 10 s. Round 3 waits only for a and b (c was behind); c, ready at 42, is in it."""
    units = {
        "a": UnitPlay([10, 10, 10], 3),
        "b": UnitPlay([20, 10, 10], 3),
        "c": UnitPlay({1: 12, 3: 10}, 3, absent=[1]),
    }
    quorum = Waits(barrier=True, quorum=0.6, grace=True)
    t = rig_time(units, 1.0, quorum)
    assert t.fleet == 42.5 and t.per_unit == {"a": 42.5, "b": 42.5, "c": 42.5}
    c = t.clocks["c"]
    assert (c.played, c.absent, c.waited) == (22, 12, 8.5)
    assert t.clocks["a"].waited == 12.5  # 10 in round 1, the grace of 2.5
    assert rig_time(units, 0.01, quorum).clocks["a"].waited == pytest.approx(0.1 + 0.25)  # the grace's floor
    everyone = rig_time(units, 1.0, Waits(barrier=True, quorum=1.0, grace=True))  # no quorum, no deadline
    assert everyone.fleet == 42 and everyone.clocks["a"].waited == 12  # 10 in round 1, 2 in round 3, for c


def test_an_absent_unit_is_charged_its_absence_without_a_barrier() -> None:
    """fedasync: nobody waits, but the unit's clock runs while it is absent: before its third round, 2 rounds'
    worth of its second round (20 steps and a reset)."""
    t = rig_time({"a": UnitPlay([10, 20, 30], 3, reset=1.0, absent=[0, 2])}, 1.0, NO_BARRIER)
    assert t.per_unit == {"a": 60 + 3 + 42} and t.clocks["a"].absent == 42


def test_a_round_of_several_episodes_resets_before_each() -> None:
    t = rig_time({"a": UnitPlay({1: 100}, 1, reset=2.0, episodes={1: 3})}, 0.02, NO_BARRIER)
    assert t.per_unit["a"] == pytest.approx(2.0 + 6.0)


def test_a_unit_that_never_completed_counts_what_it_played_and_the_fleet_waits_on() -> None:
    units = {"a": UnitPlay([10, 40, 5], 2), "b": UnitPlay([30, 20, 50], 3), "n": UnitPlay([20, 20, 20], None)}
    t = rig_time(units, 0.5, EVERYONE)
    # rounds last 30, 40, 50 steps of 0.5 s: a stops when round 2 closes, b and n when round 3 does
    assert t.per_unit == {"a": 35.0, "b": 60.0, "n": 60.0} and t.fleet == 60.0 and not t.complete
    alone = rig_time(units, 0.5, NO_BARRIER)
    assert alone.per_unit == {"a": 25.0, "b": 50.0, "n": 30.0} and alone.fleet == 50.0
    with pytest.raises(ValueError, match="completed at round 4 but played up to round 3"):
        rig_time({"a": UnitPlay([1, 2, 3], 4)}, 1.0, NO_BARRIER)
    with pytest.raises(ValueError, match="must be > 0"):
        rig_time(units, 0.0, NO_BARRIER)


def test_a_share_of_the_fleet_is_the_smallest_whole_number_of_units_at_least_that_share() -> None:
    assert [units_for(50, n) for n in (1, 2, 3, 4, 5)] == [1, 1, 2, 2, 3]
    assert [units_for(90, n) for n in (1, 4, 9, 10, 11, 1000)] == [1, 4, 9, 9, 10, 900]
    assert [units_for(100, n) for n in (1, 4, 1000)] == [1, 4, 1000]
    assert units_for(7, 100) == 7  # 0.07 × 100 is 7.000000000000001 in floats: whole numbers, no rounding up
    assert units_for(0, 4) == units_for(50, 0) == 0
    with pytest.raises(ValueError, match="must be 0"):
        units_for(101, 4)


def test_the_fleet_s_time_until_50_90_and_100_percent_of_its_units_were_controlled() -> None:
    """Alone, 1 s a step: the 4 units completed at 40, 100, 10 and 30 s. 50 % of 4 is 2 units (c, then d:
    30 s); 90 % is 3.6, so 4 units (100 s), the same as 100 %: the fleet's time."""
    units = {
        "a": UnitPlay([40], 1),
        "b": UnitPlay([20, 30, 50], 3),
        "c": UnitPlay([10, 10], 1),
        "d": UnitPlay([10, 20, 5], 2),
    }
    t = rig_time(units, 1.0, NO_BARRIER)
    assert t.per_unit == {"a": 40, "b": 100, "c": 10, "d": 30} and t.complete
    assert [t.until_controlled(p) for p in (50, 90, 100)] == [30, 100, 100] and t.fleet == 100
    assert t.to_dict()["controlled"] == {"50": 30, "90": 100, "100": 100}
    ten = rig_time({str(i): UnitPlay([10] * (i + 1), i + 1) for i in range(10)}, 0.5, NO_BARRIER)
    # unit i completes after i + 1 rounds of 5 s: 90 % of 10 is the 9th unit, at 45 s
    assert ten.to_dict()["controlled"] == {"50": 25, "90": 45, "100": 50} and ten.fleet == 50


def test_an_incomplete_fleet_has_no_time_for_the_shares_it_never_reached() -> None:
    """A round barrier, 1 s a step: rounds close at 20, 50 and 90 s. a completed in round 1 (at 20 s, when
    round 1 closed: not at its own 10), b and c in round 2 (50 s); d never did. 2 of 4 units: 50 s; 90 % and
    100 % (4 units): never reached, though the fleet's clock ran until 90 s."""
    units = {
        "a": UnitPlay([10, 10, 10], 1),
        "b": UnitPlay([20, 10, 10], 2),
        "c": UnitPlay([10, 30, 10], 2),
        "d": UnitPlay([10, 10, 40], None),
    }
    t = rig_time(units, 1.0, EVERYONE)
    assert t.per_unit == {"a": 20, "b": 50, "c": 50, "d": 90} and t.fleet == 90 and not t.complete
    assert t.to_dict()["controlled"] == {"50": 50, "90": None, "100": None}
    nobody = rig_time({"n": UnitPlay([10], None)}, 1.0, NO_BARRIER)
    assert nobody.to_dict()["controlled"] == {"50": None, "90": None, "100": None}
    assert t.until_controlled(0) == 0


def test_who_waits_follows_the_mode_the_scheme_and_the_quorum() -> None:
    assert waits_of("individual", "pergrad") == waits_of("federated", "fedasync") == NO_BARRIER
    assert waits_of("federated", "pergrad", 0.6) == Waits(barrier=True, quorum=0.6, grace=True)
    assert waits_of("federated", "fedavg") == waits_of("federated") == EVERYONE
    assert waits_of("federated", "pergrad", 0.6).rule == "round barrier, quorum 0.6"
    assert NO_BARRIER.rule == "nobody waits"


def test_the_absences_are_replayed_and_the_resets_measured_per_unit() -> None:
    settings = {"env": "qube", "fleet_seed": 1, "fleet_profile": "table2", "seed": 100, "absent": 0.2}
    plays = run_units({"0": [5] * 40, "2": [5] * 40}, {"0": None, "2": None}, settings)
    for worker in (0, 2):
        drawn = absences(0.2, 3.0, 100, worker)
        assert list(plays[str(worker)].absent) == [next(drawn) for _ in range(39)]
    assert any(plays["0"].absent) and plays["0"].absent != plays["2"].absent
    assert 1.0 < plays["0"].reset < 10.0 and plays["0"].reset == reset_seconds("qube", 0, 1, "table2")
    assert run_units({"0": [5]}, {"0": 1}, {"env": "cartpole"})["0"] == UnitPlay([5], 1)


def test_the_built_in_control_periods_are_the_devices_own() -> None:
    assert get_env_spec("qube").control_period == QubeConfig().control_period
    assert get_env_spec("qube-continuous").control_period == QubeConfig().control_period
    assert get_env_spec("cartpole").control_period == CartPoleParams().tau
