"""The uneven fleet (issue 23's QUBE target): 3 QUBE units with one at a quarter of the others' speed and
every unit absent for a random 20 % of rounds, under the default scheme (``pergrad``, its quorum 0.6; also
with its units weighed by need, ``focus`` 0.7) and the asynchronous one (``fedasync``), beside the even fleet
and each unit alone. The figure that matters is the time on the rigs (``fleetrl.runs.rig_time``: each
scheme's own waiting rule) until every unit completes."""

from fleetrl.experiments.arms import Arm
from fleetrl.experiments.budget import Budget, arm
from fleetrl.experiments.plan import Plan, Ratio

UNEVEN = {"slow": {"w2": 4.0}, "absent": 0.2}
"""the uneven fleet: unit 2 computes at a quarter of the others' speed; each unit absent for 20 % of rounds"""
DEFAULT_QUORUM = 0.6
"""``pergrad``'s own quorum (the other experiments' arms pin 1, the rule their records were made with)"""
FOCUS = 0.7
"""``pergrad``'s ``focus`` F, the units weighed by their need (docs/tuning.md, "The units furthest from
their criterion steer the step": F 0.7 on tuning seeds 0-9)"""

NOTES = (
    "Unit 2 computes 4× slower (`--slow w2=4`: it waits 3× the time each piece of its own work took); every "
    "unit is absent for a random 20 % of rounds (`--absent 0.2`). Time on the rigs counts the episodes only "
    "(6 ms a step), under each scheme's waiting rule: a per-step scheme's round lasts as long as the longest "
    "episode it waited for; under the asynchronous scheme each unit plays back to back, as alone. fedasync "
    "is not reproducible bit for bit: the order in which models arrive decides the fleet model."
)


def uneven(budget: Budget) -> Plan:
    """3 QUBE units alone, and federated even and uneven under ``pergrad`` (quorum 1 and its default 0.6) and
    ``fedasync``, preset ``standard``."""
    m, fleet_seed = budget.qube_rounds, budget.fleet_seed

    def fed(scheme: str, label: str, run: dict[str, object], focus: float = 0.0) -> Arm:
        params = {"focus": focus} if focus else None
        return arm("qube", 3, "federated", "standard", m, label, scheme, fleet_seed, None, params, run=run)

    alone = arm("qube", 3, "individual", "standard", m, "each unit alone", fleet_seed=fleet_seed)
    default: dict[str, object] = {"quorum": DEFAULT_QUORUM}
    uneven_default: dict[str, object] = {"quorum": DEFAULT_QUORUM, **UNEVEN}
    even_sync = fed("pergrad", "even · pergrad · everyone waited for", {})
    even = fed("pergrad", "even · pergrad", default)
    slow = fed("pergrad", "uneven · pergrad", uneven_default)
    even_focus = fed("pergrad", f"even · pergrad · focus {FOCUS}", default, FOCUS)
    slow_focus = fed("pergrad", f"uneven · pergrad · focus {FOCUS}", uneven_default, FOCUS)
    even_async = fed("fedasync", "even · fedasync", {})
    slow_async = fed("fedasync", "uneven · fedasync", dict(UNEVEN))
    target = "target: the uneven fleet's time on the rigs ≤ 1/2.5 of each unit alone's"
    return Plan(
        name="uneven",
        title="An uneven fleet: 3 QUBE units, one at a quarter speed, each absent 20 % of rounds",
        arms=[alone, even_sync, even, slow, even_focus, slow_focus, even_async, slow_async],
        max_rounds=m,
        ratios=[
            Ratio(alone, even_sync, "the default scheme, every worker waited for (Fig. 5's arm)"),
            Ratio(alone, even, "the default scheme with its quorum, even fleet"),
            Ratio(alone, slow, f"the default scheme, uneven fleet ({target})"),
            Ratio(
                alone, even_focus, f"the default scheme weighing units by need (focus {FOCUS}), even fleet"
            ),
            Ratio(
                alone,
                slow_focus,
                f"the default scheme weighing units by need (focus {FOCUS}), uneven fleet ({target})",
            ),
            Ratio(slow, slow_focus, "uneven fleet: units weighed by need vs the default scheme"),
            Ratio(alone, even_async, "the asynchronous scheme, even fleet"),
            Ratio(alone, slow_async, f"the asynchronous scheme, uneven fleet ({target})"),
            Ratio(slow, slow_async, "uneven fleet: asynchronous vs the default scheme"),
        ],
        notes=NOTES,
        rig_phases=True,
        headline=[alone, slow, slow_focus, slow_async, even_async],
    )
