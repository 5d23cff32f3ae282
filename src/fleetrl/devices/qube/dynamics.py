"""Compiled QUBE-Servo 2 physics and sensor pipeline, one allocation-free numba call per control period:
``reference/qube-servo2-model.md``'s equations on float64 states ``[theta, alpha, theta_dot, alpha_dot]``."""

import math

import numpy as np
from numba import njit, prange

# indices into QubeParams.coefficients()
C_M11, C_QUARTER, C_HALF, C_M22, C_GRAV, C_KM, C_RM, C_DR, C_DP = range(9)
C_THETA_OFF, C_ALPHA_OFF, C_CABLE, C_DEADBAND = range(9, 13)

# indices into the sensor array: readings (unwrapped), velocity estimates, the actuator's voltages
S_THETA, S_ALPHA, S_THETA_VEL, S_ALPHA_VEL, S_HELD, S_APPLIED = range(6)
N_SENSOR = 6

# indices into the pipeline settings array (see pipeline_settings)
P_H, P_NSUB, P_QUANTISE, P_FILTER, P_DELAY, P_VMAX = range(6)

RESOLUTION = 2.0 * math.pi / 2048.0
TWO_PI = 2.0 * math.pi


def pipeline_settings(
    period: float,
    max_substep: float,
    *,
    quantise: bool,
    velocity_filter: float | None,
    delay: bool,
    max_volts: float,
) -> np.ndarray:
    """Pack one control period's settings (``velocity_filter`` None: a finite difference over the period)."""
    n = max(1, math.ceil(period / max_substep - 1e-9))
    h = period / n
    coeff = 0.0 if velocity_filter is None else 1.0 - math.exp(-velocity_filter * h)
    return np.array([h, n, float(quantise), coeff, float(delay), max_volts], dtype=np.float64)


@njit(cache=True, inline="always")
def wrap_angle(a: float) -> float:
    """Wrap an angle to [−π, π)."""
    return a - TWO_PI * math.floor((a + math.pi) / TWO_PI)


# M(alpha)·[theta_dd, alpha_dd] = r, alpha = 0 upright (reference/qube-servo2-model.md):
#   M11 = Jr + mp·Lr² + ¼·mp·Lp²·sin²α      M12 = M21 = −½·mp·Lp·Lr·cos α      M22 = Jp + ¼·mp·Lp²
#   r1 = τ − Dr·θ̇ − Kc·θ − ½·mp·Lp²·sinα·cosα·θ̇·α̇ − ½·mp·Lp·Lr·sinα·α̇²
#   r2 = −Dp·α̇ + ¼·mp·Lp²·sinα·cosα·θ̇² + ½·mp·Lp·g·sinα
#   τ  = km·(V − km·θ̇)/Rm   (back-EMF damps the arm)
# Kc, the cable's stiffness on the arm, is 0 in the reference, as is the amplifier's dead zone Vd
# (V = sign(u)·max(|u| − Vd, 0), in dead_zone).
@njit(cache=True, inline="always")
def accelerations(
    theta: float, alpha: float, theta_dot: float, alpha_dot: float, volts: float, c: np.ndarray
) -> tuple[float, float]:
    """Solve M·[θ̈, α̈] = r for the accelerations."""
    s = math.sin(alpha)
    co = math.cos(alpha)
    m11 = c[C_M11] + c[C_QUARTER] * s * s
    m12 = -c[C_HALF] * co
    m22 = c[C_M22]
    tau = c[C_KM] * (volts - c[C_KM] * theta_dot) / c[C_RM]
    r1 = tau - c[C_DR] * theta_dot - c[C_CABLE] * theta
    r1 -= 2.0 * c[C_QUARTER] * s * co * theta_dot * alpha_dot
    r1 -= c[C_HALF] * s * alpha_dot * alpha_dot
    r2 = -c[C_DP] * alpha_dot + c[C_QUARTER] * s * co * theta_dot * theta_dot + c[C_GRAV] * s
    det = m11 * m22 - m12 * m12
    return (m22 * r1 - m12 * r2) / det, (m11 * r2 - m12 * r1) / det


@njit(cache=True, inline="always")
def rk4_step(x: np.ndarray, volts: float, c: np.ndarray, h: float) -> None:
    """Advance ``x`` in place by one classical RK4 step of length ``h`` with constant voltage."""
    t0, a0, td0, ad0 = x[0], x[1], x[2], x[3]
    k1t, k1a = accelerations(t0, a0, td0, ad0, volts, c)
    t1, a1, td1, ad1 = t0 + 0.5 * h * td0, a0 + 0.5 * h * ad0, td0 + 0.5 * h * k1t, ad0 + 0.5 * h * k1a
    k2t, k2a = accelerations(t1, a1, td1, ad1, volts, c)
    t2, a2, td2, ad2 = t0 + 0.5 * h * td1, a0 + 0.5 * h * ad1, td0 + 0.5 * h * k2t, ad0 + 0.5 * h * k2a
    k3t, k3a = accelerations(t2, a2, td2, ad2, volts, c)
    t3, a3, td3, ad3 = t0 + h * td2, a0 + h * ad2, td0 + h * k3t, ad0 + h * k3a
    k4t, k4a = accelerations(t3, a3, td3, ad3, volts, c)
    x[0] = t0 + h / 6.0 * (td0 + 2.0 * td1 + 2.0 * td2 + td3)
    x[1] = a0 + h / 6.0 * (ad0 + 2.0 * ad1 + 2.0 * ad2 + ad3)
    x[2] = td0 + h / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
    x[3] = ad0 + h / 6.0 * (k1a + 2.0 * k2a + 2.0 * k3a + k4a)


@njit(cache=True, inline="always")
def encoder(angle: float, offset: float, quantise: bool) -> float:
    """An encoder reading: whole counts (an incremental encoder counts edges) plus its zero offset."""
    if quantise:
        return RESOLUTION * math.floor(angle / RESOLUTION) + offset
    return angle + offset


@njit(cache=True, inline="always")
def filtered_rate(rate: float, delta: float, dt: float, coeff: float) -> float:
    """One update of the first-order velocity filter: ``rate`` moves by ``coeff`` towards ``delta / dt``."""
    return rate + coeff * (delta / dt - rate)


@njit(cache=True, inline="always")
def dead_zone(volts: float, width: float) -> float:
    """The amplifier's output for a command of ``volts``: nothing inside ±``width``, less ``width`` beyond."""
    if volts > width:
        return volts - width
    if volts < -width:
        return volts + width
    return 0.0


@njit(cache=True)
def control_period(
    x: np.ndarray, c: np.ndarray, sensor: np.ndarray, settings: np.ndarray, cmd: float
) -> None:
    """One control period: actuator (saturation, delay, dead zone), RK4 substeps, encoders, velocities."""
    vmax = settings[P_VMAX]
    cmd = min(max(cmd, -vmax), vmax)
    if settings[P_DELAY] != 0.0:
        volts = sensor[S_HELD]
        sensor[S_HELD] = cmd
    else:
        volts = cmd
    volts = dead_zone(volts, c[C_DEADBAND])
    sensor[S_APPLIED] = volts
    h = settings[P_H]
    n = int(settings[P_NSUB])
    quantise = settings[P_QUANTISE] != 0.0
    coeff = settings[P_FILTER]
    theta_start = sensor[S_THETA]
    alpha_start = sensor[S_ALPHA]
    for _ in range(n):
        rk4_step(x, volts, c, h)
        theta_m = encoder(x[0], c[C_THETA_OFF], quantise)
        alpha_m = encoder(x[1], c[C_ALPHA_OFF], quantise)
        if coeff > 0.0:  # filtered derivative, updated at the device's 1 ms loop
            sensor[S_THETA_VEL] = filtered_rate(sensor[S_THETA_VEL], theta_m - sensor[S_THETA], h, coeff)
            sensor[S_ALPHA_VEL] = filtered_rate(sensor[S_ALPHA_VEL], alpha_m - sensor[S_ALPHA], h, coeff)
        sensor[S_THETA] = theta_m
        sensor[S_ALPHA] = alpha_m
    if coeff <= 0.0:  # finite difference over the whole period
        sensor[S_THETA_VEL] = (sensor[S_THETA] - theta_start) / (n * h)
        sensor[S_ALPHA_VEL] = (sensor[S_ALPHA] - alpha_start) / (n * h)


@njit(cache=True)
def sense_at_rest(x: np.ndarray, c: np.ndarray, sensor: np.ndarray, quantise: bool) -> None:
    """Initialise the sensor pipeline on a state: readings of ``x``, zero velocity estimates, 0 V held."""
    sensor[S_THETA] = encoder(x[0], c[C_THETA_OFF], quantise)
    sensor[S_ALPHA] = encoder(x[1], c[C_ALPHA_OFF], quantise)
    sensor[S_THETA_VEL] = 0.0
    sensor[S_ALPHA_VEL] = 0.0
    sensor[S_HELD] = 0.0
    sensor[S_APPLIED] = 0.0


@njit(cache=True, inline="always")
def write_observation(sensor: np.ndarray, obs: np.ndarray) -> None:
    """The agent's observation: [pendulum angle (wrapped), pendulum velocity, motor angle, motor velocity]."""
    obs[0] = wrap_angle(sensor[S_ALPHA])
    obs[1] = sensor[S_ALPHA_VEL]
    obs[2] = sensor[S_THETA]
    obs[3] = sensor[S_THETA_VEL]


@njit(cache=True)
def agent_step(
    x: np.ndarray, c: np.ndarray, sensor: np.ndarray, settings: np.ndarray, cmd: float, obs: np.ndarray
) -> None:
    """What one env step costs: a control period, then the observation written into ``obs`` (float32)."""
    control_period(x, c, sensor, settings, cmd)
    write_observation(sensor, obs)


@njit(cache=True, parallel=True)
def physics_batch(
    states: np.ndarray, coefficients: np.ndarray, volts: np.ndarray, n_periods: int, n_sub: int, h: float
) -> None:
    """Raw physics: each row of ``states`` advances ``n_periods`` periods at its own constant voltage."""
    for i in prange(states.shape[0]):
        x = states[i]
        c = coefficients[i]
        v = volts[i]
        for _ in range(n_periods * n_sub):
            rk4_step(x, v, c, h)


def energy(x: np.ndarray, c: np.ndarray) -> float:
    """Total mechanical energy (J) of ``x``: ½·q̇ᵀMq̇ plus the pendulum's and the cable's potentials."""
    s = math.sin(x[1])
    m11 = c[C_M11] + c[C_QUARTER] * s * s
    m12 = -c[C_HALF] * math.cos(x[1])
    kinetic = 0.5 * (m11 * x[2] ** 2 + 2.0 * m12 * x[2] * x[3] + c[C_M22] * x[3] ** 2)
    return float(kinetic + c[C_GRAV] * math.cos(x[1]) + 0.5 * c[C_CABLE] * x[0] ** 2)
