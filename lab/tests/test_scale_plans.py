"""The fleets-of-any-size plans: CartPole (``fleet-scale``) and QUBE (``qube-scale``) share one shape."""

import pytest

from fleetrl_lab.arms import FULL, QUICK
from fleetrl_lab.catalog import ALL_EXPERIMENTS, PLANS
from fleetrl_lab.scale_plan import FLEET_SIZES, LARGE_FLEET


@pytest.mark.parametrize(
    ("name", "env", "rounds"), [("fleet-scale", "cartpole", 100), ("qube-scale", "qube", 400)]
)
def test_a_scale_plan_runs_every_fleet_size_under_pergrad_against_one_unit_alone(
    name: str, env: str, rounds: int
) -> None:
    plan = PLANS[name](FULL)
    # CartPole: one unit with the large update too; QUBE: one unit and 1,000 with the last step observed
    sizes = list(FLEET_SIZES) + ([1] if env == "cartpole" else [1, 1000])
    assert [arm.settings["units"] for arm in plan.arms] == sizes
    for arm in plan.arms:
        assert (arm.settings["env"], arm.settings["scheme"], arm.settings["max_rounds"]) == (
            env,
            "pergrad",
            rounds,
        )
    fleets = plan.arms[: len(FLEET_SIZES)]
    for arm in fleets:
        large = arm.settings["units"] >= 1000 and env == "cartpole"  # QUBE keeps the preset's update
        assert arm.settings.get("overrides", {}) == (LARGE_FLEET if large else {})
    last_step = [arm for arm in plan.arms if arm.settings.get("overrides") == {"last_step": True}]
    assert [arm.settings["units"] for arm in last_step] == ([] if env == "cartpole" else [1, 1000])
    assert [r.faster for r in plan.ratios] == fleets[1:] + last_step[1:]
    for ratio in plan.ratios:  # like for like: one unit alone with the fleet's own update
        assert ratio.slower.units == 1
        assert ratio.slower.settings.get("overrides") == ratio.faster.settings.get("overrides")
    assert plan.headline == plan.arms
    assert name not in ALL_EXPERIMENTS  # run on their own, on 5 seeds (the Makefile's results)


def test_the_quick_qube_scale_plan_keeps_the_quick_rounds() -> None:
    assert {arm.settings["max_rounds"] for arm in PLANS["qube-scale"](QUICK).arms} == {QUICK.qube_rounds}


def test_a_scale_plan_says_which_held_out_seeds_informed_its_large_fleet_choices() -> None:
    for name in ("fleet-scale", "qube-scale"):
        assert "held-out" in PLANS[name](FULL).seed_history
