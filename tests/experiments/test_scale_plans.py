"""The fleets-of-any-size plans: CartPole (``fleet-scale``) and QUBE (``qube-scale``) share one shape."""

import pytest

from fleetrl.experiments.budget import FULL, QUICK
from fleetrl.experiments.catalog import ALL_EXPERIMENTS, PLANS
from fleetrl.experiments.scale_plan import FLEET_SIZES, LARGE_FLEET


@pytest.mark.parametrize(
    ("name", "env", "rounds"), [("fleet-scale", "cartpole", 100), ("qube-scale", "qube", 400)]
)
def test_a_scale_plan_runs_every_fleet_size_under_pergrad_against_one_unit_alone(
    name: str, env: str, rounds: int
) -> None:
    plan = PLANS[name](FULL)
    assert [arm.settings["units"] for arm in plan.arms] == list(FLEET_SIZES)
    for arm in plan.arms:
        assert (arm.settings["env"], arm.settings["scheme"], arm.settings["max_rounds"]) == (
            env,
            "pergrad",
            rounds,
        )
        large = arm.settings["units"] >= 1000 and env == "cartpole"  # QUBE keeps the preset's update
        assert arm.settings.get("overrides", {}) == (LARGE_FLEET if large else {})
    alone = plan.arms[0]
    assert [(r.slower, r.faster) for r in plan.ratios] == [(alone, arm) for arm in plan.arms[1:]]
    assert plan.headline == plan.arms
    assert name not in ALL_EXPERIMENTS  # run on their own, on 5 seeds (the Makefile's results)


def test_the_quick_qube_scale_plan_keeps_the_quick_rounds() -> None:
    assert {arm.settings["max_rounds"] for arm in PLANS["qube-scale"](QUICK).arms} == {QUICK.qube_rounds}
