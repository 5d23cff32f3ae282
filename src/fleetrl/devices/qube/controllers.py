"""The rig's device-side controllers, Quanser's balance law and an energy swing-up, reading the sensor
pipeline with nominal parameters as a real unit does; ``reset_phase_step`` is one reading's reset phase
logic, looped compiled by ``device_reset`` and from Python by ``ResetPhases``."""

import math

import numpy as np
from numba import njit

from fleetrl.devices.qube.dynamics import (
    P_H,
    P_NSUB,
    S_ALPHA,
    S_ALPHA_VEL,
    S_THETA,
    S_THETA_VEL,
    control_period,
    wrap_angle,
)
from fleetrl.devices.qube.params import NOMINAL

BALANCE_GAINS = (-2.0, 35.0, -1.5, 3.0)  # Quanser's K for V = −K·x, x = [theta, alpha, theta_dot, alpha_dot]

# indices into the controller constants (see controller_constants)
K_THETA, K_ALPHA, K_THETA_DOT, K_ALPHA_DOT = range(4)
G_MU, G_TARGET_AMPLITUDE, G_ENERGY_CEILING, G_J_PIVOT, G_HALF_MGL, G_ARM_P, G_ARM_D = range(4, 11)
G_SWING_VMAX, G_CATCH, G_DROP, G_RECENTRE = range(11, 15)
G_SETTLE_ALPHA, G_SETTLE_ALPHA_DOT, G_SETTLE_THETA, G_SETTLE_THETA_DOT = range(15, 19)

CATCH_DEGREES = 20.0  # the swing-up hands over to the balance law inside this distance from upright (degrees)


def controller_constants() -> np.ndarray:
    """Pack the controllers' constants, from the *nominal* model as on a real unit (indices K_*, G_*)."""
    p = NOMINAL
    rad = math.pi / 180.0
    upright_energy = p.mp * p.g * p.Lp
    return np.array(
        [
            *BALANCE_GAINS,
            1000.0,  # swing-up pumping voltage per joule still missing (V/J)
            230.0 * rad,  # the swing amplitude (from hanging) the pumping aims at, past 180°
            1.2 * upright_energy,  # stop pumping while the pendulum's energy exceeds this
            p.Jp + 0.25 * p.mp * p.Lp**2,
            0.5 * p.mp * p.g * p.Lp,
            6.0,  # volts per radian (and per rad/s below) holding the arm near centre during swing-up
            0.2,
            8.0,  # voltage limit of the swing-up
            CATCH_DEGREES * rad,  # hand over to balance inside this distance from upright
            30.0 * rad,  # fall back to swing-up beyond this distance from upright
            0.5,  # rate (rad/s) at which the arm's set-point walks from the catch angle back to centre
            3.0 * rad,  # the hand-off windows on |alpha|, |alpha_dot|, |theta|, |theta_dot|
            1.5,
            20.0 * rad,
            1.5,
        ],
        dtype=np.float64,
    )


@njit(cache=True, inline="always")
def balance_volts(theta: float, alpha: float, theta_dot: float, alpha_dot: float, k: np.ndarray) -> float:
    """Quanser's balance law V = −K·x (alpha measured from upright)."""
    return -(
        k[K_THETA] * theta + k[K_ALPHA] * alpha + k[K_THETA_DOT] * theta_dot + k[K_ALPHA_DOT] * alpha_dot
    )


@njit(cache=True, inline="always")
def swing_up_volts(
    theta: float, alpha: float, theta_dot: float, alpha_dot: float, amplitude: float, k: np.ndarray
) -> float:
    """Energy swing-up: pumps against sign(α̇·cos α_d) (α_d from hanging), sized by the energy missing at
    the last turning point ``amplitude``; coasts while E = ½·J·α̇² + ½·mp·g·Lp·(1 − cos α_d) is above the
    ceiling; a spring-damper keeps the arm near centre."""
    cos_d = -math.cos(alpha)
    direction = alpha_dot * cos_d
    sign = 1.0 if direction > 0.0 else (-1.0 if direction < 0.0 else 0.0)
    missing = k[G_HALF_MGL] * (math.cos(amplitude) - math.cos(k[G_TARGET_AMPLITUDE]))
    pump = min(max(k[G_MU] * missing, 0.0), k[G_SWING_VMAX])
    energy = 0.5 * k[G_J_PIVOT] * alpha_dot * alpha_dot + k[G_HALF_MGL] * (1.0 - cos_d)
    if energy > k[G_ENERGY_CEILING]:
        pump = 0.0
    volts = -sign * pump - k[G_ARM_P] * theta - k[G_ARM_D] * theta_dot
    return min(max(volts, -k[G_SWING_VMAX]), k[G_SWING_VMAX])


# indices into a reset's phase memory (see reset_phase_start)
R_BALANCING, R_INSIDE, R_REFERENCE, R_AMPLITUDE, R_LAST_ALPHA_DOT, R_TRAVEL = range(6)
N_RESET_MEMORY = 6


@njit(cache=True, inline="always")
def reset_phase_start(memory: np.ndarray, alpha: float) -> None:
    """Start a reset's phase memory from the pendulum reading ``alpha`` (swinging up, nothing seen yet)."""
    memory[R_BALANCING] = 0.0
    memory[R_INSIDE] = 0.0
    memory[R_REFERENCE] = 0.0  # the balance law's arm set-point
    memory[R_AMPLITUDE] = abs(wrap_angle(alpha - math.pi))
    memory[R_LAST_ALPHA_DOT] = 0.0
    memory[R_TRAVEL] = 0.0


@njit(cache=True, inline="always")
def reset_phase_step(
    memory: np.ndarray,
    theta: float,
    alpha_reading: float,
    theta_dot: float,
    alpha_dot: float,
    k: np.ndarray,
    walk: float,
    settle_periods: int,
) -> tuple[float, bool]:
    """One period of the device-side reset: the volts to apply and whether the pendulum has settled (every
    reading inside its ``settle_*`` window for ``settle_periods`` periods in a row under the balance law,
    whose arm set-point walks from the catch angle to centre by ``walk`` rad a period). ``memory`` (from
    ``reset_phase_start``) carries the phase."""
    alpha = wrap_angle(alpha_reading)
    memory[R_TRAVEL] = max(memory[R_TRAVEL], abs(theta))
    balancing = memory[R_BALANCING] != 0.0
    if balancing and abs(alpha) > k[G_DROP]:
        balancing = False
    elif not balancing and abs(alpha) < k[G_CATCH]:
        balancing = True
        memory[R_REFERENCE] = theta
    memory[R_BALANCING] = 1.0 if balancing else 0.0
    settled = False
    if balancing:
        reference = memory[R_REFERENCE]
        reference = min(max(0.0, reference - walk), reference + walk)
        memory[R_REFERENCE] = reference
        volts = balance_volts(theta - reference, alpha, theta_dot, alpha_dot, k)
        calm = (
            abs(alpha) <= k[G_SETTLE_ALPHA]
            and abs(alpha_dot) <= k[G_SETTLE_ALPHA_DOT]
            and abs(theta) <= k[G_SETTLE_THETA]
            and abs(theta_dot) <= k[G_SETTLE_THETA_DOT]
        )
        memory[R_INSIDE] = memory[R_INSIDE] + 1.0 if calm else 0.0
        settled = memory[R_INSIDE] >= settle_periods
    else:
        memory[R_INSIDE] = 0.0
        if alpha_dot * memory[R_LAST_ALPHA_DOT] <= 0.0:  # a turning point
            memory[R_AMPLITUDE] = abs(wrap_angle(alpha - math.pi))
        volts = swing_up_volts(theta, alpha, theta_dot, alpha_dot, memory[R_AMPLITUDE], k)
    memory[R_LAST_ALPHA_DOT] = alpha_dot
    return volts, settled


class ResetPhases:
    """The device-side reset's phase machine fed one reading at a time, ``period`` seconds apart."""

    def __init__(self, period: float, settle_periods: int, constants: np.ndarray | None = None) -> None:
        self.constants = controller_constants() if constants is None else constants
        self.walk = float(self.constants[G_RECENTRE] * period)
        self.settle_periods = settle_periods
        self.memory = np.zeros(N_RESET_MEMORY, dtype=np.float64)

    def start(self, alpha: float) -> None:
        """Begin a reset with the pendulum reading ``alpha`` (rad, 0 upright)."""
        reset_phase_start(self.memory, alpha)

    def step(self, theta: float, alpha: float, theta_dot: float, alpha_dot: float) -> tuple[float, bool]:
        """The volts for this reading and whether the pendulum has settled (then the reset is over)."""
        volts, settled = reset_phase_step(
            self.memory, theta, alpha, theta_dot, alpha_dot, self.constants, self.walk, self.settle_periods
        )
        return float(volts), bool(settled)

    def hold_volts(self, theta: float, alpha: float, theta_dot: float, alpha_dot: float) -> float:
        """The swing-up law with nothing left to pump: only its arm spring-damper acts."""
        k = self.constants
        return float(swing_up_volts(theta, alpha, theta_dot, alpha_dot, k[G_TARGET_AMPLITUDE], k))


@njit(cache=True)
def device_reset(
    x: np.ndarray,
    c: np.ndarray,
    sensor: np.ndarray,
    settings: np.ndarray,
    k: np.ndarray,
    max_periods: int,
    settle_periods: int,
) -> tuple[int, float]:
    """Swing up, catch and settle: the periods used (−1: not settled in time) and the arm's travel (rad)."""
    walk = k[G_RECENTRE] * settings[P_H] * settings[P_NSUB]
    memory = np.empty(N_RESET_MEMORY, dtype=np.float64)
    reset_phase_start(memory, sensor[S_ALPHA])
    for period in range(max_periods):
        volts, settled = reset_phase_step(
            memory,
            sensor[S_THETA],
            sensor[S_ALPHA],
            sensor[S_THETA_VEL],
            sensor[S_ALPHA_VEL],
            k,
            walk,
            settle_periods,
        )
        if settled:
            return period, memory[R_TRAVEL]
        control_period(x, c, sensor, settings, volts)
    return -1, memory[R_TRAVEL]


@njit(cache=True)
def run_balance(
    x: np.ndarray, c: np.ndarray, sensor: np.ndarray, settings: np.ndarray, k: np.ndarray, n_periods: int
) -> float:
    """Run the balance law for ``n_periods``; return the largest |alpha| reading seen (rad)."""
    worst = 0.0
    for _ in range(n_periods):
        alpha = wrap_angle(sensor[S_ALPHA])
        worst = max(worst, abs(alpha))
        volts = balance_volts(sensor[S_THETA], alpha, sensor[S_THETA_VEL], sensor[S_ALPHA_VEL], k)
        control_period(x, c, sensor, settings, volts)
    return max(worst, abs(wrap_angle(sensor[S_ALPHA])))
