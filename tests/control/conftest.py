"""Fixtures of the on-unit tests: saved policies (a hand-set balancing one, and fresh ones), and the emulated
QUBE of ``tests/link`` (its directory is put on the path here)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "link"))  # qube_emulator

from control_models import balancing_model, fresh_model


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Model files, by name: ``balancing`` (QUBE, discrete: holds the pendulum), ``balancing-continuous``
    (QUBE, volts), ``balancing-own`` (a unit's own policy: the law in its own head, none in the shared),
    ``fresh`` and ``fresh-continuous`` (untrained: short episodes of varied length), ``fresh-last`` and
    ``fresh-last-continuous`` (the same, their observation with the last step),
    ``cartpole`` (untrained)."""
    out = tmp_path_factory.mktemp("models")
    return {
        "balancing": balancing_model(out / "balancing.safetensors", "qube"),
        "balancing-own": balancing_model(out / "balancing-own.safetensors", "qube", own_part="heads"),
        "balancing-continuous": balancing_model(out / "balancing-c.safetensors", "qube-continuous"),
        "fresh": fresh_model(out / "fresh.safetensors", "qube", seed=3),
        "fresh-continuous": fresh_model(out / "fresh-c.safetensors", "qube-continuous", seed=4),
        "fresh-last": fresh_model(out / "fresh-last.safetensors", "qube", seed=6, last_step=True),
        "fresh-last-continuous": fresh_model(
            out / "fresh-last-c.safetensors", "qube-continuous", seed=7, last_step=True
        ),
        "cartpole": fresh_model(out / "cartpole.safetensors", "cartpole", seed=5),
    }
