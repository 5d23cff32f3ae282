"""``fleetrl --help`` and a settings error stay quick: the command's module loads neither torch nor numba
(docs/architecture.md, "Function-level imports: only the lazy ones")."""

import subprocess
import sys

import pytest

PROBE = """
import sys
from fleetrl.cli.main import main
try:
    main({argv!r})
except SystemExit:
    pass
print("heavy:", sorted(name for name in ("torch", "numba") if name in sys.modules))
"""


@pytest.mark.parametrize("argv", [["--help"], ["train", "--help"], ["chief", "--help"], ["worker", "--help"]])
def test_help_loads_neither_torch_nor_numba(argv: list[str]) -> None:
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(argv=argv)], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.splitlines()[-1] == "heavy: []"
