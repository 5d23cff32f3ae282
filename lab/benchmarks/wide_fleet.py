"""Each unit alone against a fleet, on (learning seed, fleet seed) pairs of one fleet profile.

    python lab/benchmarks/wide_fleet.py --profile wide --pairs 100-109 [--units 3] \
        [--arm alone --arm shared --arm NAME=FLAGS] [--records lab/records/wide-fleet] [--table-only] \
        [--env module:factory]

An arm is a ``fleetrl train`` run (``alone``: ``--mode individual``; ``shared``: federated; ``NAME=FLAGS``:
other flags); each run leaves a JSON record (a recorded run is not run again). Prints per arm the completion
rounds, their ratios to alone and the time on the rigs (medians over pairs).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from fleetrl.portable import describe_host

BUILT_IN_ARMS = {"alone": ["--mode", "individual"], "shared": []}


def parse_pairs(text: str) -> list[int]:
    """``100-109`` or ``0,3,5``: the pairs' seeds."""
    if "-" in text:
        first, last = (int(x) for x in text.split("-"))
        return list(range(first, last + 1))
    return [int(x) for x in text.split(",")]


def parse_arm(text: str) -> tuple[str, list[str]]:
    """``alone``, ``shared`` or ``NAME=FLAGS``."""
    if text in BUILT_IN_ARMS:
        return text, BUILT_IN_ARMS[text]
    name, sep, flags = text.partition("=")
    if not sep or not name:
        raise SystemExit(f"an arm is alone, shared or NAME=FLAGS, got {text!r}")
    return name, shlex.split(flags)


def run_pair(
    arm_flags: list[str], pair: int, profile: str, units: int, max_rounds: int, keep: Path | None, env: str
) -> dict:
    """One run's record; ``keep``: where worker 0's model file is copied (for ``adapt_unseen.py``)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        # a unit factory (``module:factory``) draws its units itself: the profile is its own
        fleet = ["--fleet-profile", profile] if ":" not in env else []
        command = ["fleetrl", "train", "--env", env, *fleet, "--units", str(units),
                   "--seed", str(pair), "--fleet-seed", str(pair), "--max-rounds", str(max_rounds),
                   "--transport", "local", "--no-live", *arm_flags]  # fmt: skip
        done = subprocess.run([*command, "--out", str(out)], capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise SystemExit(f"{shlex.join(command)} failed:\n{done.stderr[-2000:]}")
        summary = json.loads((out / "summary.json").read_text())
        if keep is not None:
            keep.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(out / "models" / "worker-0.safetensors", keep)
    workers = summary["workers"]
    return {
        "format": 1,
        "command": shlex.join(command),
        "host": describe_host(),
        "rounds": [workers[str(u)]["completed_at_round"] for u in range(units)],
        "rig_seconds": summary["rig_seconds"],
        "wall_seconds": summary["wall_seconds"],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--profile", default="wide")
    p.add_argument("--env", default="qube", help="qube, or a unit factory module:factory of that profile")
    p.add_argument("--pairs", default="100-109")
    p.add_argument("--units", type=int, default=3)
    p.add_argument("--max-rounds", type=int, default=1000)
    p.add_argument("--arm", action="append", default=None)
    p.add_argument("--records", type=Path, default=Path("lab/records/wide-fleet"))
    p.add_argument("--table-only", action="store_true", help="print the table of the records present")
    p.add_argument(
        "--per-pair",
        action="store_true",
        help="also print, per pair and arm, the median unit's time on the rigs and waiting, and the largest "
        "mean reset",
    )
    p.add_argument("--keep-models", type=Path, default=None, help="copy worker 0's model of each run here")
    a = p.parse_args()
    arms = [parse_arm(x) for x in (a.arm or ["alone", "shared"])]
    pairs = parse_pairs(a.pairs)
    base = records_dir(a.records, a.profile, a.units, a.env)
    for name, flags in arms:
        for pair in pairs:
            path = base / name / f"pair-{pair}.json"
            if path.exists() or a.table_only:
                continue
            keep = None if a.keep_models is None else a.keep_models / name / f"pair-{pair}.safetensors"
            record = run_pair(flags, pair, a.profile, a.units, a.max_rounds, keep, a.env)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(record, indent=1) + "\n")
            print(f"{name} pair {pair}: rounds {record['rounds']}", file=sys.stderr, flush=True)
    print_table(base, [name for name, _ in arms], pairs, a.profile, a.units)
    if a.per_pair:
        print_pairs(base, [name for name, _ in arms], pairs)


def records_dir(records: Path, profile: str, units: int, env: str = "qube") -> Path:
    """Where the records of ``units``-unit fleets of ``profile`` lie: ``PROFILE-uU``, and ``-FACTORY`` after
    it for a unit factory's."""
    return records / f"{profile}-u{units}{'' if env == 'qube' else '-' + env.rpartition(':')[2]}"


def print_table(base: Path, arms: list[str], pairs: list[int], profile: str, units: int) -> None:
    """Medians over the pairs every arm has a record of; ratios against ``alone`` on those same pairs."""
    records = {arm: {pair: json.loads(f.read_text()) for pair in pairs
                     if (f := base / arm / f"pair-{pair}.json").exists()} for arm in arms}  # fmt: skip
    common = [pair for pair in pairs if all(pair in records[arm] for arm in arms)]
    print(f"{profile}, {units} units, pairs (learning seed = fleet seed) {common}; {describe_host()}")
    print("| arm | units completed | rounds per unit | last unit | × per unit | × last | rigs per unit (s) "
          "| rigs to 50 / 90 / 100 % of units (s) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    alone = _figures([records["alone"][pair] for pair in common]) if "alone" in records else None
    for arm in arms:
        fig = _figures([records[arm][pair] for pair in common])
        per, last = fig["per_unit"], fig["last"]
        ratios = ("–", "–")
        if alone is not None:
            ratios = (f"{alone['per_unit'] / per:.2f}", f"{alone['last'] / last:.2f}")
        rig_unit = "–" if math.isnan(fig["rig_unit"]) else f"{fig['rig_unit']:.0f}"
        print(
            f"| {arm} | {fig['completed']}/{fig['units']} | {per:g} | {last:g} | {ratios[0]} | {ratios[1]} "
            f"| {rig_unit} | {fig['rig_shares']} |"
        )


def print_pairs(base: Path, arms: list[str], pairs: list[int]) -> None:
    """Per pair and arm: the median unit's time on the rigs and waiting for the fleet, and the largest of its
    units' reset time per fleet round until it completed."""
    print("| pair | arm | median unit on rigs (s) | median unit waiting (s) | largest reset s per round |")
    print("|---|---|---|---|---|")
    for pair in pairs:
        for arm in arms:
            f = base / arm / f"pair-{pair}.json"
            record = json.loads(f.read_text()) if f.exists() else None
            if record is None or record["rig_seconds"] is None:
                continue
            rigs, rounds = record["rig_seconds"], record["rounds"]
            parts = zip(rigs["parts"].values(), rounds, strict=True)
            reset = max(part["reset"] / max(1, r or 1) for part, r in parts)
            median = statistics.median(rigs["per_unit"].values())
            waited = statistics.median(part["waited"] for part in rigs["parts"].values())
            print(f"| {pair} | {arm} | {median:.0f} | {waited:.0f} | {reset:.0f} |")


def _figures(records: list[dict]) -> dict:
    """Medians: rounds per unit, the last unit's rounds, time on the rigs per unit and until 50, 90 and 100 %
    of the units completed."""
    rounds = [[r if r is not None else 10**9 for r in rec["rounds"]] for rec in records]
    timed = [rec for rec in records if rec["rig_seconds"] is not None]  # a unit factory's have no clock
    flat = [r for run in rounds for r in run]
    return {
        "completed": sum(r < 10**9 for r in flat),
        "units": len(flat),
        "per_unit": statistics.median(flat) if flat else float("nan"),
        "last": statistics.median(max(run) for run in rounds) if rounds else float("nan"),
        "rig_unit": statistics.median(t for rec in timed for t in rec["rig_seconds"]["per_unit"].values())
        if timed
        else float("nan"),
        "rig_shares": " / ".join(_share_median(timed, share) for share in ("50", "90", "100")),
    }


def _share_median(records: list[dict], share: str) -> str:
    """The median over runs of the time on the rigs until ``share`` % of the units completed (≥: a run never
    got there and counts its whole time); an older record without these shares reads its units' times."""
    times, short = [], False
    for rec in records:
        rigs = rec["rig_seconds"]
        if "controlled" in rigs:
            t = rigs["controlled"].get(share)
        else:
            k = math.ceil(int(share) / 100 * len(rec["rounds"]))
            t = sorted(rigs["per_unit"].values())[k - 1] if None not in rec["rounds"] else None
        short |= t is None
        times.append(rec["rig_seconds"]["fleet"] if t is None else t)
    if not times:
        return "–"
    return ("≥ " if short else "") + f"{statistics.median(times):.0f}"


if __name__ == "__main__":
    main()
