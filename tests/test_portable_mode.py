"""The portable mode (FLEETRL_PORTABLE=1): what it pins, how it refuses to come too late, its golden scores.

The golden file holds a short seeded run's scores in portable mode. benchmarks/portable_determinism.py showed
that in this mode the scores do not change when torch, MKL, numba, numpy and glibc are made to take the code
paths of other CPUs (docs/algorithm.md, "Seeding"), so unlike any other number written down elsewhere, these
must hold on every x86-64 machine with the locked dependencies. A red test here means a change (or a
dependency) made the portable mode depend on the CPU, or changed what a seed plays.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fleetrl import portable

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden" / "portable-scores.json"
PROBE = ROOT / "benchmarks" / "portable_determinism.py"
NUMPY_OFF = portable.LIBRARY_SETTINGS["NPY_DISABLE_CPU_FEATURES"]


def python(
    code_or_argv: str | list[str], portable_mode: str | None = "1"
) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in portable.LIBRARY_SETTINGS}
    env.pop(portable.PORTABLE_ENV, None)
    if portable_mode is not None:
        env[portable.PORTABLE_ENV] = portable_mode
    argv = ["-c", code_or_argv] if isinstance(code_or_argv, str) else code_or_argv
    return subprocess.run([sys.executable, *argv], env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(("value", "expected"), [("1", True), ("on", True), ("", False), ("0", False)])
def test_the_switch_reads_on_and_off(monkeypatch: pytest.MonkeyPatch, value: str, expected: bool) -> None:
    monkeypatch.setenv(portable.PORTABLE_ENV, value)
    assert portable.enabled() is expected


def test_an_unclear_switch_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(portable.PORTABLE_ENV, "maybe")
    with pytest.raises(portable.PortableModeError, match="FLEETRL_PORTABLE='maybe': use 1"):
        portable.enabled()


@pytest.mark.slow  # a fresh Python process that imports torch
def test_importing_fleetrl_pins_every_library() -> None:
    code = (
        "import fleetrl, numba, torch\n"
        "from fleetrl.agent import policy_numpy\n"
        "from numpy._core._multiarray_umath import __cpu_dispatch__ as d, __cpu_features__ as f\n"
        "print(torch.backends.cpu.get_cpu_capability(), numba.config.CPU_NAME, policy_numpy._FASTMATH,\n"
        "      [k for k in d if f.get(k)])\n"
    )
    on, off = python(code), python(code, portable_mode=None)
    assert on.returncode == 0, on.stderr
    assert on.stdout.split() == ["DEFAULT", "generic", "False", "[]"]
    assert off.returncode == 0, off.stderr
    assert off.stdout.split()[1:3] == ["None", "True"]  # the host CPU and fastmath by default


@pytest.mark.slow  # a fresh Python process that imports torch
def test_portable_mode_after_a_torch_operation_fails_loudly() -> None:
    numpy_off = f"import os; os.environ['NPY_DISABLE_CPU_FEATURES'] = '{NUMPY_OFF}'"
    result = python(f"{numpy_off}\nimport torch\ntorch.ones(2) + 1\nimport fleetrl")
    assert result.returncode != 0
    assert "PortableModeError" in result.stderr and "PyTorch had chosen its AVX" in result.stderr


@pytest.mark.slow  # a fresh Python process that imports torch
def test_portable_mode_after_numpy_warns_what_to_set() -> None:
    result = python("import numpy\nimport fleetrl")
    assert result.returncode == 0, result.stderr
    active = python("from numpy._core._multiarray_umath import __cpu_dispatch__ as d, __cpu_features__ as f\n"
                    "print(any(f.get(k) for k in d))", portable_mode=None)  # fmt: skip
    if active.stdout.strip() == "True":
        assert (
            "RuntimeWarning" in result.stderr and f"NPY_DISABLE_CPU_FEATURES='{NUMPY_OFF}'" in result.stderr
        )
    else:
        assert "RuntimeWarning" not in result.stderr


@pytest.mark.slow
def test_a_portable_run_plays_the_golden_scores() -> None:
    golden = json.loads(GOLDEN.read_text())
    rounds = [
        "--cartpole-rounds",
        str(golden["cartpole_rounds"]),
        "--qube-rounds",
        str(golden["qube_rounds"]),
    ]
    result = python([str(PROBE), "--probe", *rounds])
    assert result.returncode == 0, result.stderr
    played = json.loads(result.stdout.strip().splitlines()[-1])
    assert played["torch_capability"] == "DEFAULT"
    assert played["scores"] == golden["scores"], (
        "the portable mode's scores changed: a change made them depend on the CPU, or changed what a seed "
        "plays (then rewrite the golden file with the command in benchmarks/portable_determinism.py)"
    )
