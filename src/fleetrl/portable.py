"""Portable mode (``FLEETRL_PORTABLE=1``): seeded runs whose scores do not depend on the host CPU.

Applied when ``fleetrl`` is imported, before numpy, numba or PyTorch choose code paths by CPU capability:
it sets their variables (:data:`LIBRARY_SETTINGS`) so every x86-64 CPU runs the same kernels
(docs/algorithm.md, "Seeding").
"""

from __future__ import annotations

import os
import sys
import warnings

PORTABLE_ENV = "FLEETRL_PORTABLE"

# What the libraries read. NUMBA_CPU_FEATURES names the baseline's sse2 explicitly: it changes no code, but
# it keys numba's on-disk cache apart from a plain `generic` build, so a cached fastmath kernel is never
# taken for a portable one.
LIBRARY_SETTINGS: dict[str, str] = {
    "ATEN_CPU_CAPABILITY": "default",
    "MKL_CBWR": "COMPATIBLE",
    "NUMBA_CPU_NAME": "generic",
    "NUMBA_CPU_FEATURES": "+sse2",
    "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
}


class PortableModeError(RuntimeError):
    """Portable mode was asked for too late to take effect in this process."""


def enabled() -> bool:
    """True when ``FLEETRL_PORTABLE`` is set to 1 (or true / yes / on)."""
    value = os.environ.get(PORTABLE_ENV, "").strip().lower()
    if value in ("", "0", "false", "no", "off"):
        return False
    if value in ("1", "true", "yes", "on"):
        return True
    raise PortableModeError(
        f"{PORTABLE_ENV}={value!r}: use 1 to turn the portable mode on, 0 to leave it off"
    )


def apply() -> None:
    """Set the libraries' variables when the mode is on; fail loudly if PyTorch already chose its kernels."""
    if not enabled():
        return
    os.environ.update(LIBRARY_SETTINGS)
    if "numba" in sys.modules:  # numba reads its target CPU from its config, refreshed from the environment
        from numba.core import config

        config.reload_config()
    if "numpy" in sys.modules:  # numpy reads its variable once, at import
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

        active = [feature for feature in __cpu_dispatch__ if __cpu_features__.get(feature)]
        if active:  # a warning, not an error: numpy's kernels were measured not to change a run's scores
            warnings.warn(
                f"{PORTABLE_ENV}=1 came after numpy was imported with its {' '.join(active)} kernels on; "
                "they were not seen to change a run, but to pin them too import fleetrl before numpy, or set "
                f"NPY_DISABLE_CPU_FEATURES='{LIBRARY_SETTINGS['NPY_DISABLE_CPU_FEATURES']}' before the "
                "process starts",
                RuntimeWarning,
                stacklevel=3,
            )
    if "torch" in sys.modules:
        import torch

        capability = torch.backends.cpu.get_cpu_capability()
        if capability != "DEFAULT":
            raise PortableModeError(
                f"{PORTABLE_ENV}=1 came after PyTorch had chosen its {capability} kernels: set it before the "
                "process starts (or import fleetrl before running any torch operation)"
            )


def host_cpu() -> str:
    """The host CPU as figures should name it: model, widest vector extension, cores (from /proc/cpuinfo)."""
    model, flags, cores = "unknown CPU", set[str](), 0
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                key, _, value = line.partition(":")
                key = key.strip()
                if key == "model name":
                    model, cores = value.strip(), cores + 1
                elif key == "flags" and not flags:
                    flags = set(value.split())
    except OSError:
        return model
    vector = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
    return f"{model}, {vector}, {cores} cores"


def describe_host() -> str:
    """One line for a figure's header: the CPU, torch and the kernels it runs, and the mode."""
    import torch

    mode = f"portable ({PORTABLE_ENV}=1)" if enabled() else "default"
    kernels = torch.backends.cpu.get_cpu_capability()
    return f"{host_cpu()}; torch {torch.__version__} ({kernels} kernels); mode {mode}"
