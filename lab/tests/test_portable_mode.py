"""The portable mode (FLEETRL_PORTABLE=1): what it pins, how it refuses to come too late, and that on one
machine its scores do not change when the libraries it does not pin take an old CPU's code paths.

The mode once had golden scores written on an AMD EPYC (AVX2) machine; an Intel Xeon (AVX-512) played
another run from them in portable mode (docs/algorithm.md, "Seeding"), so no score written down on one
machine is compared on another: the test compares two processes on the machine it runs on.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fleetrl import portable

LAB = Path(__file__).resolve().parents[1]
PROBE = LAB / "benchmarks" / "portable_determinism.py"
NUMPY_OFF = portable.LIBRARY_SETTINGS["NPY_DISABLE_CPU_FEATURES"]


def python(
    code_or_argv: str | list[str], portable_mode: str | None = "1", extra: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in portable.LIBRARY_SETTINGS}
    env.update(extra or {})
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


OLD_CPU = {"MKL_ENABLE_INSTRUCTIONS": "SSE4_2", "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA"}
"""what the portable mode does not pin itself, set as an old x86-64 CPU would have it (MKL's SSE4.2 kernels,
glibc's libm without AVX2 and FMA)"""


@pytest.mark.slow
def test_a_portable_run_plays_the_same_scores_with_an_old_cpus_code_paths() -> None:
    rounds = ["--cartpole-rounds", "20", "--qube-rounds", "4"]
    host = python([str(PROBE), "--probe", *rounds])
    old = python([str(PROBE), "--probe", *rounds], extra=OLD_CPU)
    played = []
    for result in (host, old):
        assert result.returncode == 0, result.stderr
        played.append(json.loads(result.stdout.strip().splitlines()[-1]))
    assert [p["torch_capability"] for p in played] == ["DEFAULT", "DEFAULT"]
    assert played[0]["scores"] == played[1]["scores"], (
        "in portable mode the scores changed with the code paths of another CPU: a change made the mode "
        "depend on the CPU (lab/benchmarks/portable_determinism.py shows which library)"
    )
