"""Fixtures of the command-line tests."""

from __future__ import annotations

import pytest
from cli_helpers import Fleetrl, run_fleetrl


@pytest.fixture
def fleetrl() -> Fleetrl:
    """Run the real command line: ``fleetrl("train", "--out", ...)``."""
    return run_fleetrl
