"""The bootstrap interval of a median: it holds the median, narrows with agreeing seeds, and says ``-`` for no
data."""

from fleetrl_lab.stats import Interval, bootstrap_median


def test_a_bootstrap_median_holds_the_sample_median_within_its_range() -> None:
    interval = bootstrap_median([30, 40, 50, 45, 200])
    assert interval.point == 45
    assert 30 <= interval.low <= 45 <= interval.high <= 200
    assert bootstrap_median([7, 7, 7]) == Interval(7.0, 7.0, 7.0)
    assert interval == bootstrap_median([30, 40, 50, 45, 200])  # seeded: the report does not change


def test_intervals_format_for_the_report() -> None:
    assert Interval(91.0, 80.0, 120.4).format() == "91 (80–120)"
    assert Interval(1.594, 1.1, 2.3).format(2, "×") == "1.59× (1.10–2.30)"
    assert bootstrap_median([]).format() == "-"
