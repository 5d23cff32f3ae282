"""The report sections that are not training sweeps: Table 2 (homogeneity) and the SB3 peer."""

from pathlib import Path

import numpy as np

from fleetrl.devices.homogeneity import format_tables, pooled_homogeneity, write_csv
from fleetrl_lab.arms import Arm, Budget, Places, arm
from fleetrl_lab.peers import PeerRun
from fleetrl_lab.plan import NOT_RUN, completions
from fleetrl_lab.stats import bootstrap_ratio, markdown_table, spread
from fleetrl_lab.sweep import run_all

PAPER_TABLE2 = (
    "Paper (3 real units): motor-angle correlations 0.75–0.86, pendulum-angle correlations 0.96–0.98."
)


TABLE2_FLEETS = 3
"""fleets the Table 2 section pools (the fleet seed asked for and the next ones)"""


def table2_section(
    directory: Path,
    seeds: list[int],
    preamble: list[str],
    fleet_seed: int = 0,
    units: int = 3,
    impulses: int = 100,
) -> str:
    """The homogeneity test on :data:`TABLE2_FLEETS` fleets from ``fleet_seed`` on, once per impulse seed,
    its matrices written under ``directory``: each fleet's medians and those of all pairs pooled."""
    fleets = list(range(fleet_seed, fleet_seed + TABLE2_FLEETS))
    lines = ["## Table 2: homogeneity of the simulated fleet", "", *preamble, PAPER_TABLE2, ""]
    lines += [
        f"Fleet seeds {fleets[0]}–{fleets[-1]} × impulse seeds {seeds[0]}–{seeds[-1]} ({len(seeds)}), "
        f"{units} units each, default fleet profile; one test per (fleet, impulse seed).",
        "",
    ]
    per_fleet = [pooled_homogeneity([fleet], seeds, units=units, impulses=impulses) for fleet in fleets]
    first = per_fleet[0].results[0]
    lines += [f"Fleet seed {fleets[0]}, impulse seed {seeds[0]}:", "", "```", format_tables(first), "```", ""]
    for fleet, tests in zip(fleets, per_fleet, strict=True):
        for seed, result in zip(seeds, tests.results, strict=True):
            write_csv(result, directory / f"fleet-{fleet}" / f"seed-{seed}")
    pooled = {name: np.concatenate([getattr(t, name) for t in per_fleet]) for name in PAPER_RANGES}
    rows = [
        [str(fleet), *(_spread(getattr(t, name)) for name in PAPER_RANGES)]
        for fleet, t in zip(fleets, per_fleet, strict=True)
    ]
    rows.append(
        [
            "**pooled**",
            *(
                f"{_spread(v, bold=True)}, {paper_range_verdict(float(np.median(v)), PAPER_RANGES[name])}"
                for name, v in pooled.items()
            ),
        ]
    )
    header = ["fleet seed", "motor angle: median (range)", "pendulum angle: median (range)"]
    lines += [markdown_table(header, rows), ""]
    lines += [
        f"Median of the {len(pooled['motor'])} off-diagonal pairs pooled; single pairs may fall outside the "
        "paper's ranges (three real units give one draw).",
        "",
        f"CSV matrices: `{directory.name}/fleet-*/seed-*/{{motor,pendulum}}_correlation.csv` in the "
        "experiment's --out.",
    ]
    return "\n".join(lines) + "\n"


PAPER_RANGES = {"motor": (0.75, 0.86), "pendulum": (0.96, 0.98)}
"""Table 2 of the paper: the range of its off-diagonal correlations"""


def _spread(values: np.ndarray, bold: bool = False) -> str:
    """``median (min–max)`` of correlations, the median in bold if asked."""
    median = f"**{np.median(values):.3f}**" if bold else f"{np.median(values):.3f}"
    return f"{median} ({values.min():.2f}–{values.max():.2f})"


def paper_range_verdict(median: float, paper: tuple[float, float]) -> str:
    """Whether a pooled median lies in the paper's range, in words."""
    low, high = paper
    return f"{'inside' if low <= median <= high else 'outside'} the paper's {low:.2f}–{high:.2f}"


PEER_STEPS = {"cartpole": 200_000, "qube": 100_000, "qube-continuous": 100_000}
"""SB3's step budget per unit run (each seed s trains one unit, s mod 3)"""
OUR_ARMS = ("individual", "paper", "fedavg", "pergrad")
"""fleetrl's arms next to SB3 (preset standard)"""


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
    under ``places.records/peers``). With ``run`` False nothing runs."""
    envs = ["cartpole"] if quick else list(PEER_STEPS)
    steps = {env: (5_000 if quick else PEER_STEPS[env]) for env in envs}
    fleet_seed = budget.fleet_seed
    fleet = f"fleet-{fleet_seed}" if fleet_seed else ""
    where, logs = places.records / "peers" / fleet, places.runs / "peers" / fleet

    def peer_run(env: str, s: int) -> PeerRun:
        name = f"unit-{s % 3}-seed-{s}"
        return PeerRun(
            where / env / f"{name}.json", logs / env / f"{name}.log", env, s % 3, s, steps[env], fleet_seed
        )

    peer_runs = {env: [peer_run(env, s) for s in seeds] for env in envs}
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
        rows.append([env, "SB3 PPO (defaults)", spread(sb3), f"{sb3_done}/{len(results)}", "1"])
        for scheme in OUR_ARMS:
            if not our_runs[env, scheme]:
                rows.append([env, ours[env, scheme].label, NOT_RUN, "-", "-"])
                continue
            done = completions([run.result() for run in our_runs[env, scheme]])
            per_unit = [r for c in done for r in c.worker_rounds()]
            complete = sum(r is not None for c in done for r in c.per_worker.values())
            ratio, low, high = bootstrap_ratio(per_unit, sb3)
            bound = "≤ " if sb3_done < len(results) else ""
            speed = f"{bound}{ratio:.2f}× ({low:.2f}–{high:.2f})"
            label = ours[env, scheme].label
            rows.append([env, label, spread(per_unit), f"{complete}/{len(per_unit)}", speed])
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
    hosts = {str(r.result().get("host", "not recorded")) for runs in peer_runs.values() for r in runs}
    hosts |= {r.result().host for runs in our_runs.values() for r in runs}
    lines += ["", "Runs made on: " + "; ".join(f"`{h}`" for h in sorted(hosts)) + "."]
    example = peer_run(envs[0], seeds[0])
    lines += ["", "Regenerate one SB3 unit:", "", f"    {example.command()}"]
    return "\n".join(lines) + "\n"
