"""The QUBE equations of motion and their integration: linearisation, energy, back-EMF, sensors."""

import math
from dataclasses import replace

import numpy as np
import pytest

from fleetrl.devices.qube import dynamics as d
from fleetrl.devices.qube.device import QubeDevice
from fleetrl.devices.qube.params import NOMINAL, QubeConfig

# the reference's linearisation at upright with workbook damping (Dr = 1.5e-3, Dp = 5e-4)
THETA_DD = (149.28, -17.01, -4.91, 49.73)  # coefficients of alpha, theta_dot, alpha_dot, V
ALPHA_DD = (261.61, -16.81, -8.61, 49.15)
LINEARISATION_TOLERANCE = 0.01  # the reference rounds to two decimals


def _accelerations(x: np.ndarray, volts: float, c: np.ndarray) -> np.ndarray:
    return np.array(d.accelerations(x[0], x[1], x[2], x[3], volts, c))


def test_linearisation_at_upright_matches_reference() -> None:
    c = NOMINAL.coefficients()
    eps = 1e-6
    jacobian = np.empty((2, 5))
    for j in range(4):
        step = np.zeros(4)
        step[j] = eps
        jacobian[:, j] = (_accelerations(step, 0.0, c) - _accelerations(-step, 0.0, c)) / (2 * eps)
    zero = np.zeros(4)
    jacobian[:, 4] = (_accelerations(zero, eps, c) - _accelerations(zero, -eps, c)) / (2 * eps)
    assert jacobian[:, 0] == pytest.approx([0.0, 0.0], abs=1e-6)  # no dependence on theta itself
    np.testing.assert_allclose(jacobian[0, 1:], THETA_DD, atol=LINEARISATION_TOLERANCE)
    np.testing.assert_allclose(jacobian[1, 1:], ALPHA_DD, atol=LINEARISATION_TOLERANCE)


def test_energy_conserved_without_damping_or_input() -> None:
    """Zero viscous damping and an open-circuit motor (km = 0: no current, no back-EMF), V = 0."""
    c = replace(NOMINAL, Dr=0.0, Dp=0.0).coefficients()
    c[d.C_KM] = 0.0
    x = np.array([0.0, 2.5, 3.0, -4.0])  # a large, fast swing with the arm moving
    start = d.energy(x, c)
    drift = 0.0
    for _ in range(10_000):  # 10 s at 1 ms
        d.rk4_step(x, 0.0, c, 0.001)
        drift = max(drift, abs(d.energy(x, c) - start))
    assert drift < 1e-6 * abs(start) + 1e-9, f"energy drifted by {drift:.3e} J from {start:.4f} J"


def test_back_emf_damps_the_arm() -> None:
    """With V = 0 and no viscous damping the back-EMF alone must slow a spinning arm (the known trap)."""
    c = replace(NOMINAL, Dr=0.0, Dp=0.0).coefficients()
    x = np.array([0.0, math.pi, 10.0, 0.0])  # pendulum hanging, arm spinning
    for _ in range(1000):
        d.rk4_step(x, 0.0, c, 0.001)
    assert 0.0 < x[2] < 10.0 * math.exp(-1.0) * 1.2


def test_positive_voltage_accelerates_the_arm_positively() -> None:
    theta_dd, _ = d.accelerations(0.0, 0.0, 0.0, 0.0, 1.0, NOMINAL.coefficients())
    assert theta_dd > 0


def test_substeps_never_exceed_one_millisecond() -> None:
    settings = d.pipeline_settings(
        0.006, 0.001, quantise=True, velocity_filter=None, delay=True, max_volts=10
    )
    assert settings[d.P_NSUB] == 6 and settings[d.P_H] == pytest.approx(0.001)
    settings = d.pipeline_settings(
        0.0065, 0.001, quantise=True, velocity_filter=None, delay=True, max_volts=10
    )
    assert settings[d.P_NSUB] == 7 and settings[d.P_H] <= 0.001
    with pytest.raises(ValueError, match="max_substep"):
        QubeConfig(max_substep=0.002)


def test_readings_are_whole_encoder_counts() -> None:
    device = QubeDevice(NOMINAL)
    device.set_state(np.array([0.3, 0.1, 1.0, -2.0]))
    for _ in range(20):
        device.step(2)
    resolution = 2 * math.pi / 2048
    for reading in device.readings:
        counts = reading / resolution
        assert counts == pytest.approx(round(counts), abs=1e-6)
    theta_true = device.state[0]
    assert abs(device.readings[0] - theta_true) < resolution


def test_actuation_delay_holds_the_command_one_period() -> None:
    delayed = QubeDevice(NOMINAL, QubeConfig(actuation_delay=True))
    direct = QubeDevice(NOMINAL, QubeConfig(actuation_delay=False))
    for device in (delayed, direct):
        device.set_state(np.array([0.0, math.pi, 0.0, 0.0]))
        device.step(2)
    assert delayed.applied_volts == 0.0
    assert direct.applied_volts == pytest.approx(60 * 15 / 625)
    delayed.step(1)
    assert delayed.applied_volts == pytest.approx(60 * 15 / 625)


def test_finite_difference_velocity_is_reading_change_over_period() -> None:
    device = QubeDevice(NOMINAL, QubeConfig(velocity_estimate="difference", actuation_delay=False))
    obs = device.set_state(np.array([0.0, math.pi, 0.0, 0.0]))
    before = obs.copy()
    after = device.step(2).copy()
    assert after[3] == pytest.approx((after[2] - before[2]) / 0.006, rel=1e-5)


def test_energy_with_a_cable_torque_counts_its_spring() -> None:
    """Zero damping, open-circuit motor, a cable torque −Kc·θ: energy incl. ½·Kc·θ² is conserved."""
    c = replace(NOMINAL, cable_stiffness=5e-3, Dr=0.0, Dp=0.0).coefficients()
    c[d.C_KM] = 0.0
    x = np.array([0.8, 2.5, 3.0, -4.0])
    start = d.energy(x, c)
    drift = 0.0
    for _ in range(10_000):
        d.rk4_step(x, 0.0, c, 0.001)
        drift = max(drift, abs(d.energy(x, c) - start))
    assert drift < 1e-6 * abs(start) + 1e-9
    theta_dd, _ = d.accelerations(0.5, 0.0, 0.0, 0.0, 0.0, c)
    assert theta_dd < 0  # the cable pulls the arm back towards 0


@pytest.mark.parametrize(("command", "applied"), [(1.44, 0.79), (-1.44, -0.79), (0.5, 0.0), (-0.65, 0.0)])
def test_amplifier_dead_zone(command: float, applied: float) -> None:
    device = QubeDevice(replace(NOMINAL, deadband_volts=0.65), QubeConfig(actuation_delay=False))
    device.set_state(np.array([0.0, math.pi, 0.0, 0.0]))
    device.step_volts(command)
    assert device.applied_volts == pytest.approx(applied, abs=1e-12)
