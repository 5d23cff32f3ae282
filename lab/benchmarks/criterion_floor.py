"""How much of "rounds per unit" is the completion criterion's own floor, per fleet size, from the committed
run records of the CartPole scaling experiment.

    python lab/benchmarks/criterion_floor.py [--records lab/records] [--scheme pergrad]

The criterion cannot hold before a worker's 10th round; this prints, for 1, 2, 4 and 8 workers, the median
rounds per unit, the same less the 10-round window, and both speed-ups against 1 worker.
"""

import argparse
import statistics
from pathlib import Path

from fleetrl_lab.records import read_record

WINDOW = 10
"""the criterion's window (rounds): no worker completes before its 10th round"""


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--records", type=Path, default=Path("lab/records"))
    parser.add_argument("--scheme", default="pergrad")
    parser.add_argument("--env", default="cartpole")
    args = parser.parse_args()
    base: tuple[float, float] | None = None
    print(f"{args.env}, scheme {args.scheme}: median rounds per unit (all workers of all seeds)")
    print("workers  seeds  per unit  less the window  speed-up vs 1  less the window vs 1")
    for n in (1, 2, 4, 8):
        where = args.records / f"{args.env}-{n}-federated-standard-m400-{args.scheme}"
        records = [r for p in sorted(where.glob("seed-*.json")) if (r := read_record(p)) is not None]
        rounds = [r for rec in records for r in rec.completion().worker_rounds() if r is not None]
        if not rounds:
            print(f"{n:7d}  no records")
            continue
        per_unit = statistics.median(rounds)
        above = per_unit - WINDOW
        base = base or (per_unit, above)
        seeds = ",".join(str(rec.result_settings["seed"]) for rec in records)
        print(
            f"{n:7d}  {seeds}  {per_unit:8.1f}  {above:15.1f}  {base[0] / per_unit:12.2f}×  "
            f"{base[1] / above:19.2f}×"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
