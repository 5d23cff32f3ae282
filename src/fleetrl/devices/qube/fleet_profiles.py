"""Named fleet profiles: the per-unit variations a simulated QUBE fleet can be drawn with.

A profile fixes which parameters vary between units and by how much (``QubeVariation``); the fleet seed
then fixes the draws. ``table2``, the default, is calibrated to the paper's Table 2 (docs/devices.md, "Fleet
profiles"; measured with ``lab/benchmarks/fleet_homogeneity.py``); ``v1`` is the first fleet, the one the
results before the calibration were measured on, kept so that they can be rerun (``--fleet-profile v1``).
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

FLEET_PROFILES: dict[str, FleetProfile] = {p.name: p for p in (V1, TABLE2)}
"""every profile by name"""
DEFAULT_FLEET_PROFILE = TABLE2.name
"""the profile a fleet is drawn with unless another is named"""


def fleet_profile(name: str | None = None) -> FleetProfile:
    """The profile called ``name`` (None: the default); an unknown name is a ValueError naming the choices."""
    key = DEFAULT_FLEET_PROFILE if name is None else name
    try:
        return FLEET_PROFILES[key]
    except (KeyError, TypeError):
        choices = " or ".join(FLEET_PROFILES)
        raise ValueError(f"unknown fleet profile {name!r} (choose {choices})") from None
