"""Named fleet profiles: which parameters vary between simulated QUBE units and by how much
(``QubeVariation``); the fleet seed fixes the draws. ``table2``, the default, matches the paper's Table 2;
``v1`` is the first fleet, for the results measured on it; ``wide`` spreads units as a real fleet of mixed
revisions and wear does (docs/devices.md, "Per-unit deviations and fleet profiles").
"""

from dataclasses import dataclass

from fleetrl.devices.qube.units import QubeVariation


@dataclass(frozen=True)
class FleetProfile:
    """A named per-unit variation."""

    name: str
    """the name a fleet is chosen by"""
    variation: QubeVariation
    """how far its units deviate from nominal"""
    summary: str
    """one line on what it is for"""


V1 = FleetProfile(
    "v1",
    QubeVariation(),
    "the first fleet: masses, lengths ±3 %, motor ±10 %, published damping spans; no cable, no dead zone",
)
TABLE2 = FleetProfile(
    "table2",
    QubeVariation(
        Dr_range=(5e-5, 1e-3),
        Dp_range=(1e-5, 5e-5),
        cable_stiffness_range=(5e-4, 6e-3),
    ),
    "calibrated to the paper's Table 2: v1 plus a cable torque on the arm, damping raised at the bottom",
)

WIDE = FleetProfile(
    "wide",
    QubeVariation(
        arm_mass_length=0.20,
        pendulum_mass_length=0.20,
        resistance=0.25,
        torque_constant=0.25,
        Dr_range=TABLE2.variation.Dr_range,
        Dp_range=TABLE2.variation.Dp_range,
        cable_stiffness_range=TABLE2.variation.cable_stiffness_range,
        deadband_range=(0.0, 0.2),
    ),
    "mixed revisions and wear: table2 with masses, lengths ±20 %, motor ±25 %, a dead zone to 0.2 V",
)

FLEET_PROFILES: dict[str, FleetProfile] = {p.name: p for p in (V1, TABLE2, WIDE)}
"""every profile by name"""
DEFAULT_FLEET_PROFILE = TABLE2.name
"""the profile a fleet is drawn with unless another is named"""


def fleet_profile(name: str | None = None) -> FleetProfile:
    """The profile called ``name`` (None: the default); an unknown name is a ValueError naming the choices."""
    key = DEFAULT_FLEET_PROFILE if name is None else name
    try:
        return FLEET_PROFILES[key]
    except (KeyError, TypeError):
        *others, last = FLEET_PROFILES
        choices = f"{', '.join(others)} or {last}"
        raise ValueError(f"unknown fleet profile {name!r} (choose {choices})") from None
