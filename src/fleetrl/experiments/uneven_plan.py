"""The uneven fleet (issue 23's QUBE target): 3 QUBE units with one at a quarter of the others' speed and
every unit absent for a random 20 % of rounds, under the default scheme (``pergrad``, its quorum 0.6) and the
asynchronous one (``fedasync``), beside the even fleet and each unit alone. The figure that matters is the
time on the rigs (``fleetrl.runs.rig_time``: one accounting for every arm) until every unit completes."""

from fleetrl.experiments.arms import Arm
from fleetrl.experiments.budget import Budget, arm
from fleetrl.experiments.plan import Plan, Ratio

UNEVEN: dict[str, object] = {"slow": {"w2": 4.0}, "absent": 0.2}
"""the uneven fleet: unit 2 computes at a quarter of the others' speed; each unit absent for 20 % of rounds"""
GREEDY_ONCE_HELD: dict[str, object] = {"greedy_once_held": True}
"""a unit proves itself by the policy it will run: once a round held the target, the arg-max plays on"""
DEFAULT_QUORUM = 0.6
"""``pergrad``'s own quorum (the other experiments' arms pin 1, the rule their records were made with)"""

NOTES = (
    "Unit 2 computes 4× slower (`--slow w2=4`: it waits 3× the time each piece of its own work took); "
    "every unit is absent for a random 20 % of rounds (`--absent 0.2`). Time on the rigs is one accounting "
    "for every arm: play (6 ms a step), each unit's swing-up before each episode, absences (replayed from "
    "the seed), and under `pergrad` the waits for each round's last contributor and the grace given to a "
    "unit that missed a round; under `fedasync` and alone nobody waits. Computing is left out, so the slow "
    "unit costs what it made the fleet do (rounds it missed, graces), not its own slowness. fedasync is not "
    "reproducible bit for bit: the order in which models arrive decides the fleet model."
)


def uneven(budget: Budget) -> Plan:
    """3 QUBE units alone, and federated even and uneven under ``pergrad`` (quorum 1 and its default 0.6) and
    ``fedasync``, preset ``standard``; then alone, ``pergrad`` and ``fedasync`` again with every unit proved
    by its arg-max once a round held the target (``greedy_once_held``)."""
    m, fleet_seed = budget.qube_rounds, budget.fleet_seed

    def alone_arm(label: str, overrides: dict[str, object] | None = None) -> Arm:
        return arm("qube", 3, "individual", "standard", m, label, fleet_seed=fleet_seed, overrides=overrides)

    def fed(
        scheme: str, label: str, run: dict[str, object], overrides: dict[str, object] | None = None
    ) -> Arm:
        return arm(
            "qube", 3, "federated", "standard", m, label, scheme, fleet_seed, overrides=overrides, run=run
        )

    quorum: dict[str, object] = {"quorum": DEFAULT_QUORUM}
    alone = alone_arm("each unit alone")
    even_sync = fed("pergrad", "even · pergrad · everyone waited for", {})
    even = fed("pergrad", "even · pergrad", quorum)
    slow = fed("pergrad", "uneven · pergrad", {**quorum, **UNEVEN})
    even_async = fed("fedasync", "even · fedasync", {})
    slow_async = fed("fedasync", "uneven · fedasync", UNEVEN)
    held = "arg-max once held"
    alone_greedy = alone_arm(f"each unit alone · {held}", GREEDY_ONCE_HELD)
    even_greedy = fed("pergrad", f"even · pergrad · everyone waited for · {held}", {}, GREEDY_ONCE_HELD)
    slow_greedy = fed("pergrad", f"uneven · pergrad · {held}", {**quorum, **UNEVEN}, GREEDY_ONCE_HELD)
    even_async_greedy = fed("fedasync", f"even · fedasync · {held}", {}, GREEDY_ONCE_HELD)
    slow_async_greedy = fed("fedasync", f"uneven · fedasync · {held}", UNEVEN, GREEDY_ONCE_HELD)
    target = "target: the uneven fleet's time on the rigs ≤ 1/2.5 of each unit alone's"
    both = "both proved by the arg-max"
    return Plan(
        name="uneven",
        title="An uneven fleet: 3 QUBE units, one at a quarter speed, each absent 20 % of rounds",
        arms=[
            alone,
            even_sync,
            even,
            slow,
            even_async,
            slow_async,
            alone_greedy,
            even_greedy,
            slow_greedy,
            even_async_greedy,
            slow_async_greedy,
        ],
        max_rounds=m,
        ratios=[
            Ratio(alone, even_sync, "the default scheme, every worker waited for (Fig. 5's arm)"),
            Ratio(alone, even, "the default scheme with its quorum, even fleet"),
            Ratio(alone, slow, f"the default scheme, uneven fleet ({target})"),
            Ratio(alone, even_async, "the asynchronous scheme, even fleet"),
            Ratio(alone, slow_async, f"the asynchronous scheme, uneven fleet ({target})"),
            Ratio(slow, slow_async, "uneven fleet: asynchronous vs the default scheme"),
            Ratio(
                alone,
                alone_greedy,
                "each unit alone: proved by the arg-max once held vs every episode sampled",
            ),
            Ratio(alone_greedy, even_greedy, f"the default scheme, every worker waited for, {both}"),
            Ratio(alone_greedy, slow_greedy, f"the default scheme, uneven fleet, {both} ({target})"),
            Ratio(alone_greedy, even_async_greedy, f"the asynchronous scheme, even fleet, {both}"),
            Ratio(
                alone_greedy, slow_async_greedy, f"the asynchronous scheme, uneven fleet, {both} ({target})"
            ),
            Ratio(
                alone,
                slow_async_greedy,
                "uneven fleet, asynchronous, proved by the arg-max vs each unit alone as it is",
            ),
        ],
        notes=NOTES,
        rig_phases=True,
        headline=[alone, slow, slow_async, even_async, alone_greedy, slow_greedy, slow_async_greedy],
    )
