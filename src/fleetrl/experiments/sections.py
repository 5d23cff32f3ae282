"""The report sections that are not training sweeps: Table 2 (homogeneity) and the SB3 peer."""

from pathlib import Path

import numpy as np

from fleetrl.devices.homogeneity import format_tables, homogeneity_test, write_csv
from fleetrl.experiments.arms import completions
from fleetrl.experiments.catalog import Budget, arm
from fleetrl.experiments.peers import PeerRun
from fleetrl.experiments.stats import bootstrap_ratio, markdown_table, spread
from fleetrl.experiments.sweep import run_all

PAPER_TABLE2 = (
    "Paper (3 real units): motor-angle correlations 0.75–0.86, pendulum-angle correlations 0.96–0.98."
)


def table2_section(out: Path, seeds: list[int], command: str, units: int = 3, impulses: int = 100) -> str:
    """The homogeneity test on the simulated fleet (fleet seed 0), once per impulse seed."""
    lines = [
        "## Table 2: homogeneity of the simulated fleet",
        "",
        f"Command: `{command}`",
        "",
        PAPER_TABLE2,
        "",
    ]
    off_diagonal: dict[str, list[float]] = {"motor": [], "pendulum": []}
    for seed in seeds:
        result = homogeneity_test(units, 0, impulses, seed)
        write_csv(result, out / "table2" / f"seed-{seed}")
        for name in off_diagonal:
            matrix = getattr(result, name)
            off_diagonal[name] += list(matrix[np.triu_indices(units, 1)])
        if seed == seeds[0]:
            lines += [f"Impulse seed {seed}:", "", "```", format_tables(result), "```", ""]
    for name, values in off_diagonal.items():
        lines.append(
            f"- {name} angle: off-diagonal correlations over {len(seeds)} impulse seed(s) "
            f"{min(values):.2f}–{max(values):.2f} (median {np.median(values):.2f})"
        )
    lines += ["", f"CSV matrices: `{(out / 'table2').relative_to(out.parent)}/seed-*/`"]
    return "\n".join(lines) + "\n"


PEER_STEPS = {"cartpole": 200_000, "qube": 150_000}
"""SB3's step budget per unit (QUBE: the first two seeds only, SB3 takes ~2 min per 150k QUBE steps here)"""


def peers_section(out: Path, seeds: list[int], command: str, budget: Budget, quick: bool) -> str:
    """SB3 PPO (defaults) per unit vs fleetrl on the same envs and criterion: episodes per unit."""
    envs = ["cartpole"] if quick else ["cartpole", "qube"]
    steps = {env: (5_000 if quick else PEER_STEPS[env]) for env in envs}
    peer_seeds = {env: seeds if env == "cartpole" or quick else seeds[:2] for env in envs}
    peer_runs = {
        env: [
            PeerRun(out / "peers" / env / f"unit-{u}-seed-{s}.json", env, u, s, steps[env])
            for s in peer_seeds[env]
            for u in range(3)
        ]
        for env in envs
    }
    ours = {
        "cartpole": arm("cartpole", 3, "federated", "standard", budget.cartpole_rounds, "fleetrl"),
        "qube": arm("qube", 3, "federated", "standard", budget.qube_rounds, "fleetrl"),
    }
    our_runs = {env: ours[env].runs(out / "runs", seeds) for env in envs}
    run_all([r for env in envs for r in peer_runs[env]] + [r for env in envs for r in our_runs[env]])

    lines = ["## Peers: Stable-Baselines3 PPO (defaults) per unit", "", f"Command: `{command}`", ""]
    lines += [
        "Each of 3 units trained alone by SB3 PPO with its default hyper-parameters on the same registered"
        " env, stopped by the same criterion (WMA of the last 10 scores ≥ threshold); an incomplete run"
        " counts as its episodes so far (a lower bound). fleetrl: the federated `standard` scheme, episodes"
        " per unit.",
        "",
    ]
    rows = []
    for env in envs:
        results = [r.result() for r in peer_runs[env]]
        sb3 = [r["episodes_to_completion"] or r["episodes"] for r in results]
        sb3_done = sum(r["episodes_to_completion"] is not None for r in results)
        fleet = [r for c in completions(our_runs[env]) for r in c.worker_rounds()]
        ratio, low, high = bootstrap_ratio(fleet, sb3)
        rows.append(
            [
                env,
                f"{spread(sb3)} ({sb3_done}/{len(results)} complete, ≤{steps[env]} steps)",
                f"{spread(fleet)}",
                f"{ratio:.2f}× ({low:.2f}–{high:.2f})",
            ]
        )
    lines.append(
        markdown_table(
            [
                "env",
                "SB3 PPO episodes per unit, median [IQR]",
                "fleetrl episodes per unit, median [IQR]",
                "fleetrl / SB3 (target ≤ 0.5×)",
            ],
            rows,
        )
    )
    lines += ["", "Regenerate one SB3 unit:", "", f"    {peer_runs[envs[0]][0].command()}"]
    return "\n".join(lines) + "\n"
