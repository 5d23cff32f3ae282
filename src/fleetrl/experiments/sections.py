"""The report sections that are not training sweeps: Table 2 (homogeneity) and the SB3 peer."""

from pathlib import Path

import numpy as np

from fleetrl.devices.homogeneity import format_tables, homogeneity_test, write_csv
from fleetrl.experiments.arms import Arm, Places, completions
from fleetrl.experiments.catalog import Budget, arm
from fleetrl.experiments.peers import PeerRun
from fleetrl.experiments.plan import NOT_RUN
from fleetrl.experiments.stats import bootstrap_ratio, markdown_table, spread
from fleetrl.experiments.sweep import run_all

PAPER_TABLE2 = (
    "Paper (3 real units): motor-angle correlations 0.75–0.86, pendulum-angle correlations 0.96–0.98."
)


def table2_section(
    directory: Path,
    seeds: list[int],
    preamble: list[str],
    fleet_seed: int = 0,
    units: int = 3,
    impulses: int = 100,
) -> str:
    """The homogeneity test on the simulated fleet, once per impulse seed, its matrices written under
    ``directory`` (``preamble``: the lines after the title)."""
    lines = ["## Table 2: homogeneity of the simulated fleet", "", *preamble, PAPER_TABLE2, ""]
    off_diagonal: dict[str, list[float]] = {"motor": [], "pendulum": []}
    for seed in seeds:
        result = homogeneity_test(units, fleet_seed, impulses, seed)
        write_csv(result, directory / f"seed-{seed}")
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
    lines += [
        "",
        f"CSV matrices: `{directory.name}/seed-*/{{motor,pendulum}}_correlation.csv` in the experiment's"
        " --out.",
    ]
    return "\n".join(lines) + "\n"


PEER_STEPS = {"cartpole": 200_000, "qube": 100_000, "qube-continuous": 100_000}
"""SB3's step budget per unit run. SB3 takes minutes per 100k QUBE steps here, so each seed s trains one unit
(s mod 3) instead of all three."""


OUR_ARMS = ("individual", "paper", "fedavg", "pergrad")
"""fleetrl's arms next to SB3 (preset standard): each unit alone, federated with each scheme"""


def ours_arm(env: str, name: str, rounds: int, fleet_seed: int = 0) -> Arm:
    """fleetrl's arm ``name`` of :data:`OUR_ARMS` on 3 units of ``env``."""
    if name == "individual":
        return arm(
            env, 3, "individual", "standard", rounds, "fleetrl individual · standard", fleet_seed=fleet_seed
        )
    label = f"fleetrl federated · standard · {name}"
    return arm(env, 3, "federated", "standard", rounds, label, name, fleet_seed)


def peers_section(
    places: Places, seeds: list[int], preamble: list[str], budget: Budget, quick: bool, run: bool = True
) -> str:
    """SB3 PPO (defaults) per unit vs fleetrl on the same envs and criterion: episodes per unit (SB3's results
    are records too, under ``places.records/peers``). With ``run`` False nothing runs: the section is built
    from the results there are."""
    envs = ["cartpole"] if quick else list(PEER_STEPS)
    steps = {env: (5_000 if quick else PEER_STEPS[env]) for env in envs}
    fleet_seed = budget.fleet_seed
    where = places.records / "peers" / (f"fleet-{fleet_seed}" if fleet_seed else "")
    peer_runs = {
        env: [
            PeerRun(where / env / f"unit-{s % 3}-seed-{s}.json", env, s % 3, s, steps[env], fleet_seed)
            for s in seeds
        ]
        for env in envs
    }
    rounds = {env: budget.cartpole_rounds if env == "cartpole" else budget.qube_rounds for env in envs}
    ours = {
        (env, scheme): ours_arm(env, scheme, rounds[env], fleet_seed) for env in envs for scheme in OUR_ARMS
    }
    our_runs = {key: ours[key].runs(places, seeds) for key in ours}
    if run:
        run_all([r for env in envs for r in peer_runs[env]] + [r for runs in our_runs.values() for r in runs])
    else:
        peer_runs = {env: [r for r in runs if r.done] for env, runs in peer_runs.items()}
        our_runs = {key: [r for r in runs if r.done] for key, runs in our_runs.items()}

    lines = ["## Peers: Stable-Baselines3 PPO (defaults) per unit", "", *preamble]
    lines += [
        "Each of 3 units trained alone by SB3 PPO with its default hyper-parameters on the same registered"
        " env, stopped by the same criterion (WMA of the last 10 scores ≥ threshold); an incomplete run"
        " counts as its episodes so far (a lower bound). SB3's step budget per unit run: "
        + ", ".join(f"{env} {steps[env]:,}" for env in envs)
        + " (seed s trains unit s mod 3).",
        "",
    ]
    rows = []
    for env in envs:
        results = [r.result() for r in peer_runs[env]]
        if not results:
            rows.append([env, "SB3 PPO (defaults)", NOT_RUN, "-", "-"])
            continue
        sb3 = [r["episodes_to_completion"] or r["episodes"] for r in results]
        sb3_done = sum(r["episodes_to_completion"] is not None for r in results)
        rows.append([env, "SB3 PPO (defaults)", f"{spread(sb3)}", f"{sb3_done}/{len(results)}", "1"])
        for scheme in OUR_ARMS:
            if not our_runs[env, scheme]:
                rows.append([env, ours[env, scheme].label, NOT_RUN, "-", "-"])
                continue
            done = completions([run.result() for run in our_runs[env, scheme]])
            fleet = [r for c in done for r in c.worker_rounds()]
            complete = sum(r is not None for c in done for r in c.per_worker.values())
            ratio, low, high = bootstrap_ratio(fleet, sb3)
            label = ours[env, scheme].label
            rows.append(
                [
                    env,
                    label,
                    f"{spread(fleet)}",
                    f"{complete}/{len(fleet)}",
                    f"{'≤ ' if sb3_done < len(results) else ''}{ratio:.2f}× ({low:.2f}–{high:.2f})",
                ]
            )
    lines.append(
        markdown_table(
            [
                "env",
                "learner",
                "episodes per unit to completion, median [IQR] (range)",
                "units complete",
                "episodes / SB3's (target ≤ 0.5×; 95 % bootstrap)",
            ],
            rows,
        )
    )
    example = PeerRun(
        where / envs[0] / "unit-0-seed-0.json", envs[0], 0, seeds[0], steps[envs[0]], fleet_seed
    )
    lines += ["", "Regenerate one SB3 unit:", "", f"    {example.command()}"]
    return "\n".join(lines) + "\n"
