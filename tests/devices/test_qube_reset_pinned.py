"""The compiled device-side reset gives, to the bit, what it gave before its phase logic became the shared
``reset_phase_step`` (digest recorded from the fused loop of commit 46fdb48)."""

from __future__ import annotations

import hashlib
from dataclasses import replace

from fleetrl.devices.qube.device import QubeDevice
from fleetrl.devices.qube.params import NOMINAL

UNITS = [
    replace(NOMINAL, Dr=2e-4, Dp=2e-5),
    replace(NOMINAL, Dr=5e-5, Dp=1e-5, Rm=9.0),
    replace(NOMINAL, Dr=1e-4, Dp=5e-6, km=0.039, alpha_offset_counts=2, deadband_volts=0.3),
]
DIGEST = "d0e0780b7e1869197eef05f061b6cc535d847d719728a5be3281f2a51bd581a4"


def test_the_compiled_reset_is_bit_identical_to_the_fused_loop() -> None:
    digest = hashlib.sha256()
    for params in UNITS:
        for seed in range(3):
            device = QubeDevice(params)
            obs = device.reset(seed)
            digest.update(obs.tobytes())
            digest.update(device.state.tobytes())
            digest.update(repr((device.last_reset_seconds, device.last_reset_arm_travel)).encode())
    assert digest.hexdigest() == DIGEST
