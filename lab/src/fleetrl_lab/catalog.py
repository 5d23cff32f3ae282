"""The experiments ``fleetrl experiment NAME`` knows (:data:`PLANS`; the uneven fleet and fleets of up to
1,000 units in their own modules, Table 2 and the SB3 peer in :mod:`fleetrl_lab.sections`)."""

from collections.abc import Callable

from fleetrl_lab.arms import Arm, Budget, arm
from fleetrl_lab.plan import Plan, Ratio
from fleetrl_lab.scale_plan import fleet_scale, qube_scale
from fleetrl_lab.uneven_plan import argmax, uneven

SERVER_OPTIMISERS = {
    "fedavgm": {"server_lr": 1.0, "momentum": 0.5},
    "fedadam": {"server_lr": 0.03},
}
"""the server optimisers' best settings on the tuning seeds (lab/tuning.md, CartPole, 3 units)"""


PERGRAD_QUBE_MEMORY = 500
"""the trajectory memory per worker that made ``pergrad`` fastest on 3 QUBE units (lab/tuning.md)"""
FIG_SERVER_OPTIMISER = "fedavgm"
"""the server optimiser Fig. 5, Fig. 6 and the CartPole scaling study run too (it beat fedavg and fedadam)"""


def scheme_arm(env: str, units: int, rounds: int, label: str, scheme: str, budget: Budget) -> Arm:
    """A federated arm with preset ``standard`` and ``scheme`` (a server optimiser: its tuned settings)."""
    params = SERVER_OPTIMISERS.get(scheme)
    if params:
        label += f" ({', '.join(f'{k} {v:g}' for k, v in params.items())})"
    return arm(env, units, "federated", "standard", rounds, label, scheme, budget.fleet_seed,
               budget.target_score, params)  # fmt: skip


def pergrad_memory_arm(units: int, rounds: int, label: str, budget: Budget) -> Arm:
    """``pergrad`` on QUBE with :data:`PERGRAD_QUBE_MEMORY`, preset ``standard``."""
    overrides: dict[str, object] = {"memory_size": PERGRAD_QUBE_MEMORY}
    return arm("qube", units, "federated", "standard", rounds, f"{label} · memory {PERGRAD_QUBE_MEMORY}",
               "pergrad", budget.fleet_seed, overrides=overrides)  # fmt: skip


def fig5(budget: Budget) -> Plan:
    """3 QUBE units: individual vs federated, with the paper's preset as written and as its code ran
    (``paper-code``) and with ``standard``; fleetrl's schemes (``fedavg``, ``pergrad``) with ``standard``."""
    m = budget.qube_rounds
    ind_paper, fed_paper, ind_std, fed_std = (
        arm("qube", 3, mode, preset, m, f"{mode} · {preset}", "paper", budget.fleet_seed)
        for preset in ("paper", "standard")
        for mode in ("individual", "federated")
    )
    fedavg, pergrad = (
        arm("qube", 3, "federated", "standard", m, f"federated · standard · {s}", s, budget.fleet_seed)
        for s in ("fedavg", "pergrad")
    )
    ind_code, fed_code = (
        arm("qube", 3, mode, "paper-code", m, f"{mode} · paper-code", "paper", budget.fleet_seed)
        for mode in ("individual", "federated")
    )
    server = FIG_SERVER_OPTIMISER
    optimised = scheme_arm("qube", 3, m, f"federated · standard · {server}", server, budget)
    memory = PERGRAD_QUBE_MEMORY
    pergrad_tuned = pergrad_memory_arm(3, m, "federated · standard · pergrad", budget)
    return Plan(
        name="fig5",
        title="Fig. 5: 3 QUBE units, individual vs federated",
        arms=[
            ind_paper,
            fed_paper,
            ind_code,
            fed_code,
            ind_std,
            fed_std,
            fedavg,
            optimised,
            pergrad,
            pergrad_tuned,
        ],
        max_rounds=m,
        ratios=[
            Ratio(ind_paper, fed_paper, "the paper: ≈1.5× overall, 2.7× on the slowest unit"),
            Ratio(ind_std, fed_std, "the paper's scheme with the standard preset"),
            Ratio(ind_std, fedavg, "model averaging vs each unit alone"),
            Ratio(fed_std, fedavg, "model averaging vs the paper's scheme, same preset"),
            Ratio(fed_paper, pergrad, "fleetrl's default scheme vs the paper's scheme and preset"),
            Ratio(ind_code, fed_code, "the paper's scheme as its code ran (paper-code preset)"),
            Ratio(
                ind_std,
                pergrad,
                "fleetrl's default scheme (per-step gradient averaging) vs each unit alone "
                "(target: 2.7× for the fleet, 2× per unit)",
            ),
            Ratio(fedavg, pergrad, "per-step gradient averaging vs model averaging"),
            Ratio(fedavg, optimised, f"server optimiser: {server} vs fedavg"),
            Ratio(
                ind_std,
                pergrad_tuned,
                f"pergrad with the memory tuned for it ({memory} per worker) vs each unit alone with the "
                "preset's 1000 (each arm its own best preset; target: 2.7× for the fleet)",
            ),
        ],
        side_by_side=(ind_std, pergrad),
        mqtt_check=pergrad,
        notes="Paper (3 real units): ≈300 rounds federated vs 820 / 820 / 571 individual.",
        headline=[ind_std, fedavg, pergrad, pergrad_tuned],
    )


def fig6(budget: Budget) -> Plan:
    """2 vs 3 QUBE workers, federated, with each scheme."""
    m = budget.qube_rounds
    variants = (
        ("paper", "paper"), ("paper-code", "paper"), ("standard", "paper"), ("standard", "fedavg"),
        ("standard", FIG_SERVER_OPTIMISER), ("standard", "pergrad"),
    )  # fmt: skip

    def one(n: int, preset: str, scheme: str) -> Arm:
        label = f"{n} workers · {preset} · {scheme}"
        if preset == "standard":
            return scheme_arm("qube", n, m, label, scheme, budget)
        return arm("qube", n, "federated", preset, m, label, scheme, budget.fleet_seed)

    arms = {(n, *v): one(n, *v) for v in variants for n in (2, 3)}
    # pergrad with the memory tuned for it at 3 workers (Fig. 5), the same memory at 2
    tuned = {n: pergrad_memory_arm(n, m, f"{n} workers · standard · pergrad", budget) for n in (2, 3)}
    paper_claim = "the paper: 3 workers ≈ 1.38× faster than 2"
    return Plan(
        name="fig6",
        title="Fig. 6: 2 vs 3 workers, federated (QUBE)",
        arms=[*arms.values(), *tuned.values()],
        max_rounds=m,
        ratios=[Ratio(arms[2, *v], arms[3, *v], paper_claim) for v in variants]
        + [Ratio(tuned[2], tuned[3], paper_claim)],
        mqtt_check=arms[3, "standard", "fedavg"],
        headline=[a for (_, preset, scheme), a in arms.items() if scheme in ("fedavg", "pergrad")]
        + list(tuned.values()),
    )


def cartpole_scaling(budget: Budget) -> Plan:
    """1, 2, 4, 8 CartPole workers, federated, preset standard, with each scheme."""
    m = budget.cartpole_rounds
    env = budget.unit_type or "cartpole"
    schemes = ("paper", "fedavg", FIG_SERVER_OPTIMISER, "pergrad")
    arms = {
        (n, scheme): scheme_arm(env, n, m, f"{n} workers · standard · {scheme}", scheme, budget)
        for scheme in schemes
        for n in (1, 2, 4, 8)
    }
    return Plan(
        name="cartpole-scaling",
        title=f"{'CartPole' if env == 'cartpole' else env} scaling: 1, 2, 4, 8 workers, federated "
        "(preset standard)",
        arms=list(arms.values()),
        max_rounds=m,
        ratios=[
            Ratio(arms[1, scheme], arms[n, scheme], "the paper's earlier study: faster with more workers")
            for scheme in schemes
            for n in (2, 4, 8)
        ],
        mqtt_check=arms[4, "fedavg"],
        headline=[a for (_, scheme), a in arms.items() if scheme in ("fedavg", "pergrad")],
        notes=PAPER_CARTPOLE_LOGS if env == "cartpole" else "",
    )


PAPER_CARTPOLE_LOGS = (
    "The paper's code, its published CartPole logs (another criterion: a plain mean ≥ 195 over 100 episodes; "
    "12 runs per arm; its paper-scheme federation): mean rounds per worker, federated / independent, 464 / "
    "367 with 2 workers, 356 / 459 with 4, 314 / 388 with 8 (0.79×, 1.29×, 1.24×)."
)
"""what the authors' code measured on CartPole (docs/algorithm.md; the reference anchors)"""


PAPER_CODE_BUDGET = 5
"""the CartPole paper-code arm also runs with this many times the budget"""
HEADLINE_MODES = ("individual", "fedavg", "pergrad")
"""the learning experiment's headline arms (preset standard)"""


def learning(budget: Budget) -> Plan:
    """3 units of each env, individual and federated, both presets; fedavg, pergrad and (CartPole and a user's
    unit type) the server optimisers with ``standard`` (lab/benchmarks/learning.py)."""
    arms: dict[tuple[str, str, str], Arm] = {}
    ratios = []
    envs = [("cartpole", budget.cartpole_rounds), ("qube", budget.qube_rounds)]
    if budget.unit_type is not None:
        envs = [(budget.unit_type, budget.cartpole_rounds)]
    target = budget.target_score
    for env, rounds in envs:
        for preset in ("paper", "standard"):
            for mode in ("individual", "federated"):
                label = f"{env} · {mode} · {preset}"
                arms[env, preset, mode] = arm(
                    env, 3, mode, preset, rounds, label, "paper", budget.fleet_seed, target_score=target
                )
            alone = arms[env, preset, "individual"]
            ratios.append(Ratio(alone, arms[env, preset, "federated"], "federation, the paper's scheme"))
        for scheme in ("fedavg", "pergrad"):  # with the preset that learns
            label = f"{env} · federated · standard · {scheme}"
            fed = arm(env, 3, "federated", "standard", rounds, label, scheme, budget.fleet_seed, target)
            arms[env, "standard", scheme] = fed
            ratios.append(Ratio(arms[env, "standard", "individual"], fed, f"federation, {scheme}"))
        fedavg = arms[env, "standard", "fedavg"]
        if env != "qube":  # tuned on CartPole; not run on QUBE (each QUBE arm costs ~15 min per seed here)
            for scheme in SERVER_OPTIMISERS:
                label = f"{env} · federated · standard · {scheme}"
                optimised = scheme_arm(env, 3, rounds, label, scheme, budget)
                arms[env, "standard", scheme] = optimised
                ratios.append(Ratio(fedavg, optimised, f"server optimiser: {scheme} vs fedavg"))
        arms[env, "paper-code", "individual"] = arm(
            env, 3, "individual", "paper-code", rounds, f"{env} · individual · paper-code",
            fleet_seed=budget.fleet_seed, target_score=target,
        )  # fmt: skip
        if env == "cartpole":  # the authors' CartPole logs needed 367-464 rounds per worker
            long = PAPER_CODE_BUDGET * rounds
            arms[env, "paper-code", "long"] = arm(
                env, 3, "individual", "paper-code", long, f"{env} · individual · paper-code · M {long}",
                fleet_seed=budget.fleet_seed, target_score=target,
            )  # fmt: skip
    return Plan(
        name="learning",
        title="Learning speed: 3 units of each env, each alone and federated with each scheme, each preset",
        arms=list(arms.values()),
        max_rounds=max(rounds for _, rounds in envs),
        ratios=ratios,
        notes="Rounds = episodes per unit, except with the paper-code preset (a round: the episodes that "
        "fill its memory of ≥ 200 transitions). SB3 PPO on the same envs and criterion: see the Peers "
        "section.",
        headline=[
            a for (_, preset, how), a in arms.items() if preset == "standard" and how in HEADLINE_MODES
        ],
    )


def continuous(budget: Budget) -> Plan:
    """3 QUBE units with the motor voltage as a continuous action (``qube-continuous``: a Gaussian policy)
    next to the paper's three actions (``qube``): alone, ``fedavg`` and ``pergrad``, preset ``standard``."""
    m, fleet_seed = budget.qube_rounds, budget.fleet_seed

    def one(env: str, scheme: str) -> Arm:
        if scheme == "alone":
            return arm(env, 3, "individual", "standard", m, f"{env} · alone", fleet_seed=fleet_seed)
        return arm(env, 3, "federated", "standard", m, f"{env} · federated · {scheme}", scheme, fleet_seed)

    schemes = ("alone", "fedavg", "pergrad")
    arms = {(env, s): one(env, s) for env in ("qube", "qube-continuous") for s in schemes}
    continuous_alone = arms["qube-continuous", "alone"]
    return Plan(
        name="continuous",
        title="Continuous actions: 3 QUBE units, motor voltage in [−3, 3] V vs the paper's three actions",
        arms=list(arms.values()),
        max_rounds=m,
        ratios=[
            *(
                Ratio(arms["qube-continuous", s], arms["qube", s], f"continuous vs three actions: {s}")
                for s in schemes
            ),
            *(
                Ratio(continuous_alone, arms["qube-continuous", s], "continuous: federated vs alone")
                for s in schemes[1:]
            ),
        ],
        side_by_side=(continuous_alone, arms["qube-continuous", "pergrad"]),
        mqtt_check=arms["qube-continuous", "pergrad"],
        notes="In the first three ratios a figure above 1 means the three-action task completed sooner. The "
        "unseen-unit columns score each final policy greedily (the Gaussian's mean) on units no worker "
        "trained on.",
    )


PLANS: dict[str, Callable[[Budget], Plan]] = {
    "fig5": fig5,
    "fig6": fig6,
    "cartpole-scaling": cartpole_scaling,
    "learning": learning,
    "continuous": continuous,
    "uneven": uneven,
    "argmax": argmax,
    "fleet-scale": fleet_scale,
    "qube-scale": qube_scale,
}
EXPERIMENTS = (*PLANS, "table2", "peers")
ALL_EXPERIMENTS = tuple(
    name for name in EXPERIMENTS if name not in ("uneven", "argmax", "fleet-scale", "qube-scale")
)
"""what ``fleetrl experiment all`` runs (the others run on their own: the Makefile's ``results``)"""
UNIT_TYPE_EXPERIMENTS = ("learning", "cartpole-scaling")
"""the experiments not about the paper's rig: they also train a user's unit type (``--env``)"""
