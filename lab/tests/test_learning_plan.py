"""The experiments' arms of the server optimisers: their tuned settings, next to fedavg, out of the headline
arms; the learning experiment runs both on CartPole, the figures the one that won there."""

from pathlib import Path

import pytest

from fleetrl_lab.arms import FULL
from fleetrl_lab.catalog import FIG_SERVER_OPTIMISER, PLANS, SERVER_OPTIMISERS, learning


def test_server_optimisers_run_on_cartpole_with_their_tuned_settings() -> None:
    plan = learning(FULL)
    optimised = [a for a in plan.arms if a.settings.get("scheme") in SERVER_OPTIMISERS]
    assert sorted(a.settings["scheme"] for a in optimised) == ["fedadam", "fedavgm"]
    assert all(a.settings["env"] == "cartpole" for a in optimised)
    fedavgm = next(a for a in optimised if a.settings["scheme"] == "fedavgm")
    command = fedavgm.command(Path("out"))
    assert "--scheme fedavgm --scheme-param server_lr=1.0 --scheme-param momentum=0.5" in command
    # the parameters are part of the key, so a run with other parameters is never reused for this arm
    assert fedavgm.key.startswith("cartpole-3-federated-standard-m400-fedavgm-")
    assert fedavgm.key != fedavgm.with_settings(scheme_params={"server_lr": 1.0, "momentum": 0.9}).key


def test_each_server_optimiser_is_compared_with_fedavg_and_is_no_headline_arm() -> None:
    plan = learning(FULL)
    versus_fedavg = {
        r.faster.settings["scheme"] for r in plan.ratios if r.slower.settings.get("scheme") == "fedavg"
    }
    assert versus_fedavg == set(SERVER_OPTIMISERS)
    headline = {(a.settings["env"], a.settings.get("scheme", "alone")) for a in plan.headline}
    assert headline == {(env, s) for env in ("cartpole", "qube") for s in ("alone", "fedavg", "pergrad")}


def test_a_server_optimiser_is_compared_with_each_unit_alone_too() -> None:
    from fleetrl_lab.plan import alone_arm

    plan = learning(FULL)
    for optimised in (a for a in plan.arms if a.settings.get("scheme") in SERVER_OPTIMISERS):
        alone = alone_arm(plan, optimised)
        assert alone is not None and alone.key == "cartpole-3-individual-standard-m400"


@pytest.mark.parametrize("name", ["fig5", "fig6", "cartpole-scaling"])
def test_the_figures_run_the_server_optimiser_that_won_with_its_settings(name: str) -> None:
    plan = PLANS[name](FULL)
    optimised = [a for a in plan.arms if a.settings.get("scheme") == FIG_SERVER_OPTIMISER]
    assert optimised and all(
        a.settings["scheme_params"] == SERVER_OPTIMISERS[FIG_SERVER_OPTIMISER] for a in optimised
    )
    assert not set(optimised) & set(plan.headline)
    assert all(any(a in (r.faster, r.slower) for r in plan.ratios) for a in optimised)  # each compared
    assert not any(a.settings.get("scheme") == "fedadam" for a in plan.arms)  # lost on CartPole: dropped
