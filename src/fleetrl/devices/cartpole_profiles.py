"""Named CartPole fleet profiles: how far each per-unit parameter of a simulated CartPole deviates from
CartPole-v1's (``CartPoleVariation``); the fleet seed fixes the draws. ``standard``, the default, is the fleet
every CartPole run was made on (each ±10 %); ``wide`` spreads units as a fleet of mixed builds does (each
±40 %). docs/devices.md, "CartPole", gives their homogeneity figures.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class CartPoleVariation:
    """How far units deviate: each parameter is its nominal value times a factor drawn uniformly from
    [1 − spread, 1 + spread] (a spread below 1, so every unit's masses, length and force stay positive).
    Gravity and the step (τ) are nominal on every unit."""

    masscart: float = 0.10
    masspole: float = 0.10
    length: float = 0.10
    """of the half-pole"""
    force_mag: float = 0.10

    def __post_init__(self) -> None:
        for name, spread in vars(self).items():
            if not 0.0 <= spread < 1.0:
                raise ValueError(f"{name} spread must be in [0, 1) so units stay physical, got {spread!r}")


@dataclass(frozen=True)
class CartPoleFleetProfile:
    """A named per-unit variation of CartPole units."""

    name: str
    """the name a fleet is chosen by"""
    variation: CartPoleVariation
    """how far its units deviate from nominal"""
    summary: str
    """one line on what it is for"""


STANDARD = CartPoleFleetProfile(
    "standard",
    CartPoleVariation(),
    "the fleet every CartPole run was made on: cart mass, pole mass, pole length and push force each ±10 %",
)
WIDE = CartPoleFleetProfile(
    "wide",
    CartPoleVariation(masscart=0.40, masspole=0.40, length=0.40, force_mag=0.40),
    "a fleet of mixed builds: cart mass, pole mass, pole length and push force each ±40 %",
)

CARTPOLE_FLEET_PROFILES: dict[str, CartPoleFleetProfile] = {p.name: p for p in (STANDARD, WIDE)}
"""every profile by name"""
DEFAULT_CARTPOLE_FLEET_PROFILE = STANDARD.name
"""the profile a fleet is drawn with unless another is named"""


def cartpole_fleet_profile(name: str | None = None) -> CartPoleFleetProfile:
    """The profile called ``name`` (None: the default); an unknown name is a ValueError naming the choices."""
    key = DEFAULT_CARTPOLE_FLEET_PROFILE if name is None else name
    try:
        return CARTPOLE_FLEET_PROFILES[key]
    except (KeyError, TypeError):
        *others, last = CARTPOLE_FLEET_PROFILES
        choices = f"{', '.join(others)} or {last}"
        raise ValueError(f"unknown cartpole fleet profile {name!r} (choose {choices})") from None
