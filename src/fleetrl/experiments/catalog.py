"""The training experiments ``fleetrl experiment NAME`` knows: the paper's Fig. 5 and Fig. 6, and the CartPole
scaling study (Table 2 and the SB3 peer are in :mod:`fleetrl.experiments.sections`)."""

from collections.abc import Callable
from dataclasses import dataclass

from fleetrl.experiments.arms import Arm
from fleetrl.experiments.plan import Plan, Ratio


@dataclass(frozen=True)
class Budget:
    """How many rounds (the paper's M) the runs of an experiment may take."""

    qube_rounds: int
    cartpole_rounds: int


FULL = Budget(qube_rounds=1000, cartpole_rounds=400)
QUICK = Budget(qube_rounds=4, cartpole_rounds=6)


def train_args(env: str, units: int, mode: str, preset: str, rounds: int) -> tuple[str, ...]:
    """``fleetrl train`` arguments of an arm (federated arms use the in-process bus)."""
    args = [
        "--env",
        env,
        "--units",
        str(units),
        "--mode",
        mode,
        "--preset",
        preset,
        "--max-rounds",
        str(rounds),
    ]
    if mode == "federated":
        args += ["--transport", "local"]
    return tuple(args)


def fig5(budget: Budget) -> Plan:
    """3 QUBE units: individual vs federated, with the paper's preset and with ``standard``."""
    m = budget.qube_rounds
    arms = [
        Arm(f"{mode}-{preset}", f"{mode} · {preset}", train_args("qube", 3, mode, preset, m))
        for preset in ("paper", "standard")
        for mode in ("individual", "federated")
    ]
    return Plan(
        name="fig5",
        title="Fig. 5: 3 QUBE units, individual vs federated",
        arms=arms,
        max_rounds=m,
        ratios=[
            Ratio(
                "individual-paper", "federated-paper", "the paper: ≈1.5× overall, 2.7× on the slowest unit"
            ),
            Ratio("individual-standard", "federated-standard", "federation with the standard preset"),
            Ratio("individual-paper", "federated-standard", "fleetrl's best scheme vs the paper's baseline"),
            Ratio("federated-paper", "federated-standard", "fleetrl's best scheme vs the paper's scheme"),
        ],
        side_by_side=("individual-standard", "federated-standard"),
        mqtt_check="federated-standard",
        notes="Paper (3 real units): ≈300 rounds federated vs 820 / 820 / 571 individual.",
    )


def fig6(budget: Budget) -> Plan:
    """2 vs 3 QUBE workers, federated."""
    m = budget.qube_rounds
    arms = [
        Arm(
            f"federated-{n}-{preset}",
            f"{n} workers · {preset}",
            train_args("qube", n, "federated", preset, m),
        )
        for preset in ("paper", "standard")
        for n in (2, 3)
    ]
    return Plan(
        name="fig6",
        title="Fig. 6: 2 vs 3 workers, federated (QUBE)",
        arms=arms,
        max_rounds=m,
        ratios=[
            Ratio("federated-2-paper", "federated-3-paper", "the paper: 3 workers ≈ 1.38× faster than 2"),
            Ratio("federated-2-standard", "federated-3-standard", "the same with the standard preset"),
        ],
        mqtt_check="federated-3-standard",
    )


def cartpole_scaling(budget: Budget) -> Plan:
    """1, 2, 4, 8 CartPole workers, federated."""
    m = budget.cartpole_rounds
    arms = [
        Arm(
            f"federated-{n}-{preset}",
            f"{n} workers · {preset}",
            train_args("cartpole", n, "federated", preset, m),
        )
        for preset in ("paper", "standard")
        for n in (1, 2, 4, 8)
    ]
    return Plan(
        name="cartpole-scaling",
        title="CartPole scaling: 1, 2, 4, 8 workers, federated",
        arms=arms,
        max_rounds=m,
        ratios=[
            Ratio(
                "federated-1-standard", "federated-8-standard", "the paper's earlier study: faster with more"
            ),
            Ratio("federated-1-paper", "federated-8-paper", "the same with the paper's preset"),
        ],
        mqtt_check="federated-4-standard",
    )


PLANS: dict[str, Callable[[Budget], Plan]] = {
    "fig5": fig5,
    "fig6": fig6,
    "cartpole-scaling": cartpole_scaling,
}
EXPERIMENTS = (*PLANS, "table2", "peers")
