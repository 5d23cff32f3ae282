"""An agent built or loaded only to act or to be evaluated imports no ``torch._dynamo`` (1.5-2 s of start-up
in every such process; the agent tests' updates step optimisers built the same way)."""

import subprocess
import sys
from pathlib import Path

SCRIPT = """
import sys
from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent

agent = PPOAgent(4, 2, get_preset("standard"), seed=0)
agent.save(sys.argv[1])
PPOAgent.load(sys.argv[1])
print("torch._dynamo" in sys.modules)
"""


def test_building_and_loading_an_agent_imports_no_dynamo(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path / "model.safetensors")],
        capture_output=True, text=True, check=True, timeout=120,
    )  # fmt: skip
    assert out.stdout.split() == ["False"], out.stderr
