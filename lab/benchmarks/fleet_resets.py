"""How often a QUBE fleet profile's units need a hand reset: each unit's device-side swing-up, seeded.

    python lab/benchmarks/fleet_resets.py --profile wide [--units 100] [--fleet-seeds 0 1 2] [--resets 5]

Prints the units whose swing-up did not settle within its time limit in at least one of ``--resets`` seeded
resets (on a rig, a person puts the pendulum upright), how many resets that was and why
(``QubeDevice.last_unsettled``: held up but not settled, or never caught), and the swing-up's seconds.
"""

from __future__ import annotations

import argparse
import logging
from collections import Counter

import numpy as np

from fleetrl.devices.factory import make_device
from fleetrl.devices.qube.device import QubeDevice


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="table2")
    parser.add_argument("--units", type=int, default=100)
    parser.add_argument("--fleet-seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--resets", type=int, default=5)
    args = parser.parse_args()
    logging.disable(logging.WARNING)  # each unit that needs a hand says so once; counted below instead
    by_hand, units_by_hand, seconds, why = 0, 0, [], Counter[str]()
    for fleet_seed in args.fleet_seeds:
        for unit in range(args.units):
            device = make_device("qube", unit, fleet_seed, fleet_profile=args.profile)
            assert isinstance(device, QubeDevice)
            hands, total = 0, 0.0
            for seed in range(args.resets):
                device.reset(seed=seed)
                total += device.last_reset_seconds
                hands += int(device.last_reset_by_hand)
                if device.last_reset_by_hand:
                    why[device.last_unsettled.partition(":")[0]] += 1
            by_hand += hands
            units_by_hand += hands > 0
            seconds.append(total / args.resets)
    n = len(seconds)
    print(
        f"profile {args.profile}: {n} units (fleet seeds {' '.join(map(str, args.fleet_seeds))}, "
        f"{args.units} each), {args.resets} seeded resets each"
    )
    print(f"  units needing a hand reset: {units_by_hand} ({100 * units_by_hand / n:.1f} %)")
    print(f"  resets by hand: {by_hand} of {n * args.resets}")
    for reason, count in why.most_common():
        print(f"    {reason}: {count}")
    print(f"  swing-up, s per unit: median {np.median(seconds):.2f}, max {max(seconds):.2f}")


if __name__ == "__main__":
    main()
