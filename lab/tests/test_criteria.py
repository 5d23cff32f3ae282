"""One criterion per comparison: a ratio never divides a run proved one way by a run proved another."""

import pytest

from fleetrl_lab.arms import FULL, arm
from fleetrl_lab.catalog import PLANS
from fleetrl_lab.plan import Ratio


def test_a_ratio_across_two_criteria_is_refused() -> None:
    sampled = arm("qube", 3, "individual", "standard", 1000, "alone")
    argmax = arm("qube", 3, "individual", "standard", 1000, "alone", overrides={"criterion": "argmax"})
    assert (sampled.criterion, argmax.criterion) == ("sampled", "argmax")
    with pytest.raises(ValueError, match="compare arms of one criterion"):
        Ratio(sampled, argmax, "the arg-max proof vs sampling")
    Ratio(argmax, argmax.with_settings(units=3), "one criterion on both sides")  # allowed


def test_the_argmax_experiment_is_the_uneven_one_with_every_arm_under_the_argmax_criterion() -> None:
    uneven, argmax = PLANS["uneven"](FULL), PLANS["argmax"](FULL)
    assert {a.criterion for a in uneven.arms} == {"sampled"}
    assert {a.criterion for a in argmax.arms} == {"argmax"}
    strip = [{**a.settings, "overrides": None} for a in argmax.arms]
    assert strip == [{**a.settings, "overrides": None} for a in uneven.arms]
    assert len(argmax.ratios) == len(uneven.ratios)


@pytest.mark.parametrize("name", sorted(PLANS))
def test_every_ratio_of_every_experiment_divides_one_criterion(name: str) -> None:
    for ratio in PLANS[name](FULL).ratios:
        assert ratio.slower.criterion == ratio.faster.criterion
