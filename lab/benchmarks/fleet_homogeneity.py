"""The paper's Table 2 homogeneity test pooled over fleet and impulse seeds, for one fleet profile.

    python lab/benchmarks/fleet_homogeneity.py --profile table2 --fleet-seeds 0-2 --impulse-seeds 0-4
    python lab/benchmarks/fleet_homogeneity.py --env cartpole --profile wide

Prints the median (and range) of the off-diagonal motor- and pendulum-angle correlations of the fleets next
to the paper's rig (motor 0.75–0.86, pendulum 0.96–0.98); with ``--env cartpole``, of the cart- and
pole-change correlations and relative differences of every unit pair (docs/devices.md has the figures).
"""

import argparse

import numpy as np

from fleetrl.devices.cartpole import CARTPOLE_FLEET_PROFILES, DEFAULT_CARTPOLE_FLEET_PROFILE
from fleetrl.devices.homogeneity import pooled_cartpole_homogeneity, pooled_homogeneity
from fleetrl.devices.qube.params import DEFAULT_FLEET_PROFILE, FLEET_PROFILES

PAPER = {"motor": (0.75, 0.86), "pendulum": (0.96, 0.98)}
"""off-diagonal ranges of the paper's Table 2 (three real units)"""
PROFILES = {
    "qube": (DEFAULT_FLEET_PROFILE, sorted(FLEET_PROFILES)),
    "cartpole": (DEFAULT_CARTPOLE_FLEET_PROFILE, sorted(CARTPOLE_FLEET_PROFILES)),
}
"""each unit type's default profile and its profiles"""


def seed_range(text: str) -> range:
    """``"0-2"`` → range(0, 3); ``"4"`` → range(4, 5)."""
    low, _, high = text.partition("-")
    try:
        first, last = int(low), int(high or low)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a seed or a range like 0-4, got {text!r}") from None
    if first < 0 or last < first:
        raise argparse.ArgumentTypeError(f"expected 0 <= first <= last, got {text!r}")
    return range(first, last + 1)


def main() -> None:
    """Parse the arguments, run the pooled test, print one line per angle (CartPole: per part)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="qube", choices=sorted(PROFILES))
    parser.add_argument("--profile", default=None, help="the unit type's fleet profile (default: its own)")
    parser.add_argument("--fleet-seeds", type=seed_range, default=range(3))
    parser.add_argument("--impulse-seeds", type=seed_range, default=range(5))
    parser.add_argument("--units", type=int, default=3)
    args = parser.parse_args()
    default, profiles = PROFILES[args.env]
    profile = default if args.profile is None else args.profile
    if profile not in profiles:
        parser.error(f"--profile {profile!r}: a {args.env} fleet's profiles are {', '.join(profiles)}")
    seeds = f"fleet seeds {args.fleet_seeds.start}-{args.fleet_seeds.stop - 1}"
    seeds += f" x impulse seeds {args.impulse_seeds.start}-{args.impulse_seeds.stop - 1}"
    if args.env == "cartpole":
        print_cartpole(args.fleet_seeds, args.impulse_seeds, args.units, profile, seeds)
        return
    pooled = pooled_homogeneity(args.fleet_seeds, args.impulse_seeds, units=args.units, profile=profile)
    print(f"fleet profile {pooled.profile}, {args.units} units, {seeds}: {pooled.motor.size} pairs")
    for name, values in (("motor", pooled.motor), ("pendulum", pooled.pendulum)):
        low, high = PAPER[name]
        median = float(np.median(values))
        verdict = "inside" if low <= median <= high else "outside"
        print(
            f"  {name:8s} median {median:.3f}  range {values.min():.3f}-{values.max():.3f}  "
            f"(paper {low:.2f}-{high:.2f}: median {verdict})"
        )


def print_cartpole(fleet_seeds: range, seeds: range, units: int, profile: str, described: str) -> None:
    """The CartPole test's pooled figures, one line per part (cart, pole)."""
    pooled = pooled_cartpole_homogeneity(fleet_seeds, seeds, units=units, profile=profile)
    pairs = pooled.cart_correlation.size
    print(f"cartpole fleet profile {pooled.profile}, {units} units, {described}: {pairs} pairs")
    for name, correlation, difference in (
        ("cart", pooled.cart_correlation, pooled.cart_difference),
        ("pole", pooled.pole_correlation, pooled.pole_difference),
    ):
        print(
            f"  {name}  correlation median {np.median(correlation):.4f} range "
            f"{correlation.min():.4f}-{correlation.max():.4f}  relative difference median "
            f"{np.median(difference):.3f} range {difference.min():.3f}-{difference.max():.3f}"
        )


if __name__ == "__main__":
    main()
