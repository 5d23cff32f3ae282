"""A fleet of any size (issue 24's learning at scale): CartPole fleets of 1, 8, 64, 256 and 1,000 units
under the default scheme (``pergrad``, every member waited for), preset ``standard``; above 16 units the
units run in unit hosts of about one per core (``--units-per-host auto``, the default). The 1,000-unit fleet
updates on windows of 16 transitions per unit instead of the preset's 128 (docs/tuning.md: an eighth of the
update's arithmetic, chosen on tuning seed 0). The figures that matter: rounds per unit against each unit
alone, and whether a larger fleet keeps paying."""

from fleetrl.experiments.arms import Arm
from fleetrl.experiments.budget import Budget, arm
from fleetrl.experiments.plan import Plan, Ratio

FLEET_SIZES = (1, 8, 64, 256, 1000)
"""the fleets measured"""
SCALE_ROUNDS = 100
"""M of every arm (each unit alone completes within it on every held-out seed measured: median 60); a full
budget's 400 would let one slow unit of 1,000 hold the fleet for an hour"""
LARGE_FLEET_WINDOW = 16
"""the window per unit (``batch_size``) of the 1,000-unit fleet"""

NOTES = (
    "Above 16 units the units of a fleet run in unit hosts, about one per core (two on the machine that made "
    "these records), each one member of the federation carrying its units; a unit keeps its own env, seed, "
    "criterion and rows. Every member is waited for at every step (quorum 1), as in the CartPole scaling "
    "study. The 1,000-unit fleet updates on windows of 16 transitions per unit (`--set batch_size=16`), the "
    "others on the preset's 128."
)


def fleet_scale(budget: Budget) -> Plan:
    """CartPole fleets of :data:`FLEET_SIZES` units under ``pergrad``, preset ``standard``, M =
    :data:`SCALE_ROUNDS` (or the budget's CartPole rounds if fewer: ``--quick``)."""
    m = min(SCALE_ROUNDS, budget.cartpole_rounds)

    def fleet(n: int) -> Arm:
        window: dict[str, object] | None = {"batch_size": LARGE_FLEET_WINDOW} if n >= 1000 else None
        label = ("1 unit alone" if n == 1 else f"{n} units") + " · pergrad"
        label += f" · window {LARGE_FLEET_WINDOW}" if window else ""
        fleet_seed = budget.fleet_seed
        return arm("cartpole", n, "federated", "standard", m, label, "pergrad", fleet_seed, overrides=window)

    arms = {n: fleet(n) for n in FLEET_SIZES}
    alone = arms[1]
    return Plan(
        name="fleet-scale",
        title="A fleet of any size: 1 to 1,000 CartPole units under pergrad",
        arms=list(arms.values()),
        max_rounds=m,
        ratios=[
            Ratio(alone, arms[n], "target at 1,000 units: ≥ 3× fewer rounds per unit than alone")
            for n in FLEET_SIZES[1:]
        ],
        notes=NOTES,
        headline=list(arms.values()),
    )
