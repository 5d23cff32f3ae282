"""The bootstrap interval of a median and of a ratio of medians: it holds the point, stays the interval the
records' reports show, and says ``-`` for no data."""

import numpy as np

from fleetrl_lab.stats import Interval, bootstrap_median, bootstrap_ratio


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


def test_a_bootstrap_ratio_is_the_ratio_of_medians_resampled_as_one_draw_after_another() -> None:
    alone, fleet = [162, 140, 300, 151, 177, 233, 98], [71, 60, 95, 88, 64]
    point, low, high = bootstrap_ratio(alone, fleet, seed=3, draws=40)
    assert point == 162 / 71
    rng = np.random.default_rng(3)  # the resampling written plainly: each draw resamples both samples
    ratios = [np.median(rng.choice(alone, 7)) / np.median(rng.choice(fleet, 5)) for _ in range(40)]
    assert (low, high) == tuple(np.percentile(ratios, [2.5, 97.5]))
    assert bootstrap_ratio([4, 4], [2], draws=50) == (2.0, 2.0, 2.0)
