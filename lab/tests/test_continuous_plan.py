"""The continuous experiment: its discrete arms are Fig. 5's runs, its continuous arms the Box task."""

from fleetrl_lab.arms import FULL
from fleetrl_lab.catalog import PLANS


def test_discrete_arms_reuse_fig5_runs_and_continuous_arms_train_the_box_task() -> None:
    plan = PLANS["continuous"](FULL)
    fig5_keys = {arm.key for arm in PLANS["fig5"](FULL).arms}
    discrete = [arm for arm in plan.arms if arm.settings["env"] == "qube"]
    continuous = [arm for arm in plan.arms if arm.settings["env"] == "qube-continuous"]
    assert len(discrete) == len(continuous) == 3
    assert {arm.key for arm in discrete} <= fig5_keys  # the same settings: the runs are shared, not rerun
    assert {arm.key for arm in continuous}.isdisjoint(fig5_keys)
    assert plan.mqtt_check in continuous
    # each continuous arm sits next to the discrete arm with the same mode and scheme
    strip = [{k: v for k, v in a.settings.items() if k != "env"} for a in (*discrete, *continuous)]
    assert strip[:3] == strip[3:]
