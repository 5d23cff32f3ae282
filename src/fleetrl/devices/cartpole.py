"""CartPole units: Gymnasium CartPole-v1 physics (``gymnasium.envs.classic_control.CartPoleEnv``: its
equations, constants, start states and Euler integrator) with per-unit cart mass, pole mass, pole length and
push force, and the named fleet profiles they are drawn with: ``standard`` (each ±10 %, the default) and
``wide`` (each ±40 %, a fleet of mixed builds)."""

import math
from dataclasses import dataclass

import numpy as np

from fleetrl.devices.variation import CARTPOLE_FAMILY, FleetProfile, named_profile, scaled, unit_generator

X_LIMIT = 2.4  # cart position beyond which an episode ends (m)
THETA_LIMIT = 12.0 * 2.0 * math.pi / 360.0  # pole angle beyond which an episode ends (rad)


@dataclass(frozen=True)
class CartPoleParams:
    """Physical constants of one CartPole unit (CartPole-v1 defaults)."""

    gravity: float = 9.8
    masscart: float = 1.0
    masspole: float = 0.1
    length: float = 0.5  # half the pole's length (m), as in Gymnasium
    force_mag: float = 10.0
    tau: float = 0.02  # seconds per step


CARTPOLE_NOMINAL = CartPoleParams()


@dataclass(frozen=True)
class CartPoleVariation:
    """How far units deviate: each parameter times a factor uniform in [1 − spread, 1 + spread]."""

    masscart: float = 0.10
    masspole: float = 0.10
    length: float = 0.10
    force_mag: float = 0.10

    def __post_init__(self) -> None:
        for name, spread in vars(self).items():
            if not 0.0 <= spread < 1.0:
                raise ValueError(f"{name} spread must be in [0, 1) so units stay physical, got {spread!r}")


STANDARD = FleetProfile(
    "standard",
    CartPoleVariation(),
    "the fleet every CartPole run was made on: cart mass, pole mass, pole length and push force each ±10 %",
)
WIDE = FleetProfile(
    "wide",
    CartPoleVariation(masscart=0.40, masspole=0.40, length=0.40, force_mag=0.40),
    "a fleet of mixed builds: cart mass, pole mass, pole length and push force each ±40 %",
)
CARTPOLE_FLEET_PROFILES: dict[str, FleetProfile[CartPoleVariation]] = {p.name: p for p in (STANDARD, WIDE)}
DEFAULT_CARTPOLE_FLEET_PROFILE = STANDARD.name


def cartpole_fleet_profile(name: str | None = None) -> FleetProfile[CartPoleVariation]:
    """The CartPole profile called ``name`` (None: the default); an unknown name is a ValueError."""
    return named_profile(
        CARTPOLE_FLEET_PROFILES, name, DEFAULT_CARTPOLE_FLEET_PROFILE, "cartpole fleet profile"
    )


def cartpole_unit_params(
    fleet_seed: int, unit: int, variation: CartPoleVariation | None = None
) -> CartPoleParams:
    """The parameters of CartPole unit ``unit`` of fleet ``fleet_seed`` (None: the default profile's)."""
    spread = cartpole_fleet_profile().variation if variation is None else variation
    rng = unit_generator(fleet_seed, unit, CARTPOLE_FAMILY)
    n = CARTPOLE_NOMINAL
    return CartPoleParams(
        gravity=n.gravity,
        masscart=scaled(rng, n.masscart, spread.masscart),
        masspole=scaled(rng, n.masspole, spread.masspole),
        length=scaled(rng, n.length, spread.length),
        force_mag=scaled(rng, n.force_mag, spread.force_mag),
        tau=n.tau,
    )


class CartPoleDevice:
    """One CartPole unit; observation [x, x_dot, theta, theta_dot] (float32)."""

    def __init__(self, params: CartPoleParams | None = None) -> None:
        self.params = params or CARTPOLE_NOMINAL
        self._state = [0.0, 0.0, 0.0, 0.0]
        self._obs = np.zeros(4, dtype=np.float32)

    @classmethod
    def from_fleet(cls, unit: int, fleet_seed: int, *, profile: str | None = None) -> "CartPoleDevice":
        """Unit ``unit`` of fleet ``fleet_seed`` drawn with fleet profile ``profile`` (None: the default)."""
        return cls(cartpole_unit_params(fleet_seed, unit, cartpole_fleet_profile(profile).variation))

    @property
    def state(self) -> np.ndarray:
        """A copy of the state [x, x_dot, theta, theta_dot] in float64."""
        return np.array(self._state, dtype=np.float64)

    def set_state(self, state: np.ndarray) -> None:
        """Put the unit in state [x, x_dot, theta, theta_dot] (a batch that stepped it hands it back)."""
        self._state = [float(v) for v in state]
        self._obs[:] = self._state

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start state uniform in ±0.05 on every component, as CartPole-v1."""
        rng = np.random.default_rng(seed)
        self._state = [float(v) for v in rng.uniform(-0.05, 0.05, size=4)]
        self._obs[:] = self._state
        return self._obs

    def step(self, action: int) -> np.ndarray:
        """Push left (0) or right (1) for one step of ``tau`` seconds (explicit Euler, as CartPole-v1)."""
        if action != 0 and action != 1:
            raise ValueError(f"action {action!r} is out of range (choose 0: push left, or 1: push right)")
        p = self.params
        x, x_dot, theta, theta_dot = self._state
        force = p.force_mag if action == 1 else -p.force_mag
        cos_t = math.cos(theta)
        sin_t = math.sin(theta)
        total_mass = p.masspole + p.masscart
        pole_mass_length = p.masspole * p.length
        temp = (force + pole_mass_length * theta_dot**2 * sin_t) / total_mass
        theta_acc = (p.gravity * sin_t - cos_t * temp) / (
            p.length * (4.0 / 3.0 - p.masspole * cos_t**2 / total_mass)
        )
        x_acc = temp - pole_mass_length * theta_acc * cos_t / total_mass
        x += p.tau * x_dot
        x_dot += p.tau * x_acc
        theta += p.tau * theta_dot
        theta_dot += p.tau * theta_acc
        self._state = [x, x_dot, theta, theta_dot]
        self._obs[:] = self._state
        return self._obs

    def close(self) -> None:
        """Nothing to release."""


class CartPoleForceUnit:
    """A CartPole commanded by ``[force fraction]``: its sign pushes right or left; 0 brakes the cart."""

    def __init__(self, device: CartPoleDevice) -> None:
        self.device = device
        self._obs = np.zeros(4, dtype=np.float32)

    def reset(self, seed: int | None = None) -> np.ndarray:
        """The unit's reset."""
        self._obs = self.device.reset(seed)
        return self._obs

    def step(self, action: np.ndarray) -> np.ndarray:
        """One period pushed the way ``action[0]``'s sign says (0: braked); returns the observation."""
        value = float(action[0])
        if value != 0.0:
            self._obs = self.device.step(1 if value > 0.0 else 0)
        return self._obs

    def close(self) -> None:
        """Close the unit."""
        self.device.close()
