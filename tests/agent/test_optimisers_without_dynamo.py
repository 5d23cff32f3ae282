"""An agent built, trained, saved and loaded imports no ``torch._dynamo`` (1.5-2 s of start-up in every
process that builds one), and its optimisers step as ``optimiser.step()`` does."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import torch

from fleetrl.agent.optimisers import step_optimiser

SCRIPT = """
import sys
import numpy as np
from fleetrl.agent.config import get_preset
from fleetrl.agent.ppo import PPOAgent

agent = PPOAgent(4, 2, get_preset("standard"), seed=0)
rng = np.random.default_rng(0)
obs = rng.normal(size=4).astype(np.float32)
for i in range(300):
    nxt = rng.normal(size=4).astype(np.float32)
    agent.remember(obs, agent.act(obs), 1.0, nxt, terminated=(i % 30 == 29), truncated=False)
    obs = nxt
agent.update()
agent.apply_actor_gradient(agent.actor_gradient())
agent.save(sys.argv[1])
PPOAgent.load(sys.argv[1])
print("torch._dynamo" in sys.modules)
"""


def test_an_agent_built_trained_and_loaded_imports_no_dynamo(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path / "model.safetensors")],
        capture_output=True, text=True, check=True, timeout=120,
    )  # fmt: skip
    assert out.stdout.split() == ["False"], out.stderr


def test_a_step_moves_the_parameters_and_the_state_as_torch_s_own_step() -> None:
    nets, optimisers = [], []
    for _ in range(2):
        torch.manual_seed(0)
        net = torch.nn.Linear(4, 2)
        nets.append(net)
        optimisers.append(torch.optim.Adam(net.parameters(), lr=0.01))
    for k in range(3):
        for net in nets:
            net.zero_grad()
            (net(torch.full((3, 4), float(k + 1))) ** 2).sum().backward()
        optimisers[0].step()
        step_optimiser(optimisers[1])
    assert all(torch.equal(a, b) for a, b in zip(nets[0].parameters(), nets[1].parameters(), strict=True))
    assert not torch.equal(nets[1].weight, torch.nn.Linear(4, 2).weight)
    state = optimisers[1].state_dict()["state"][0]
    assert float(state["step"]) == 3 and np.any(state["exp_avg"].numpy() != 0)
