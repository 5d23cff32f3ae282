"""``fleetrl export``: a model file's greedy policy written as an ONNX graph (opset 17) built node by node
from the actor's weights (``observation`` in; ``action`` out, a discrete action's index or a box's clipped
mean; ``fleetrl`` metadata), then checked: onnxruntime must pick fleetrl's actions on observations half from
the unit's own episodes and half drawn around them (a box's within a float32 tolerance)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fleetrl.agent.policy_file import PolicyFile, read_policy_file
from fleetrl.control.policies import ModelPolicy, OnnxPolicy, check_fits
from fleetrl.envs.catalog import describe_env, get_env_spec

FORMAT = "fleetrl.policy/1"  # the ``format`` in every exported file's ``fleetrl`` metadata
OPSET = 17
IR_VERSION = 8
INPUT = "observation"
OUTPUT = "action"


def policy_metadata(policy: PolicyFile, env: str | None) -> dict[str, Any]:
    """What an exported file records about its policy (the ``fleetrl`` metadata, as a dict)."""
    return {
        "format": FORMAT,
        "obs_dim": policy.obs_dim,
        "last_step": policy.last_step,
        "action_space": policy.action_space.to_dict(),
        "action": "index" if policy.action_space.is_discrete else "clipped mean",
        "env": env,
        "source": policy.source,
    }


def policy_graph(policy: PolicyFile, env: str | None = None) -> Any:
    """The greedy policy of ``policy`` as an ``onnx.ModelProto`` (checked), ``env`` in its metadata."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    initialisers: list[Any] = []
    nodes: list[Any] = []

    def constant(name: str, array: np.ndarray) -> str:
        initialisers.append(numpy_helper.from_array(np.asarray(array, dtype=np.float32), name))
        return name

    x = INPUT
    activation = "Tanh" if policy.activation == "tanh" else "Relu"
    last = len(policy.layers) - 1
    for i, (weight, bias) in enumerate(policy.layers):
        name = "policy" if i == last else f"trunk.{i}"
        w, b = constant(f"{name}.weight", weight), constant(f"{name}.bias", bias)
        out = f"{name}.linear"
        nodes.append(helper.make_node("Gemm", [x, w, b], [out], transB=1, name=f"{name}.gemm"))
        if i < last:
            x = f"{name}.out"
            nodes.append(helper.make_node(activation, [out], [x], name=f"{name}.{activation.lower()}"))
        else:
            x = out
    space = policy.action_space
    if space.is_discrete:
        nodes.append(helper.make_node("ArgMax", [x], [OUTPUT], axis=1, keepdims=0, name="greedy"))
        output = helper.make_tensor_value_info(OUTPUT, TensorProto.INT64, ["batch"])
    else:
        half, centre = constant("half_range", space.half_range()), constant("centre", space.centre())
        low, high = constant("low", np.asarray(space.low)), constant("high", np.asarray(space.high))
        nodes += [
            helper.make_node("Mul", [x, half], ["scaled"], name="scale"),
            helper.make_node("Add", ["scaled", centre], ["mean"], name="mean"),
            helper.make_node("Max", ["mean", low], ["above_low"], name="clip_low"),
            helper.make_node("Min", ["above_low", high], [OUTPUT], name="clip_high"),
        ]
        output = helper.make_tensor_value_info(OUTPUT, TensorProto.FLOAT, ["batch", space.dim])
    observation = helper.make_tensor_value_info(INPUT, TensorProto.FLOAT, ["batch", policy.obs_dim])
    metadata = policy_metadata(policy, env)
    graph = helper.make_graph(nodes, "fleetrl_greedy_policy", [observation], [output], initialisers)
    model = helper.make_model(
        graph,
        producer_name="fleetrl",
        opset_imports=[helper.make_opsetid("", OPSET)],
        ir_version=IR_VERSION,
        doc_string=f"greedy policy of {policy.source}: observation -> {metadata['action']}",
    )
    helper.set_model_props(model, {"fleetrl": json.dumps(metadata, sort_keys=True)})
    onnx.checker.check_model(model)
    return model


CHECK_OBSERVATIONS = 1000  # observations ``fleetrl export`` checks the exported file on
RELATIVE_TOLERANCE = 1e-5
"""a box's actions agree when they differ by at most this fraction of the half range (float32 rounding)"""
STEPS_PER_OBSERVATION = 4
"""the unit's episodes run for up to this many steps per observation wanted (then half are picked)"""


@dataclass(frozen=True)
class ExportCheck:
    """How the exported graph's actions compared with fleetrl's."""

    observations: int  # observations checked
    agreeing: int  # how many got the same action (a box's: within the tolerance)
    max_difference: float  # a box's largest absolute difference in any component (0 for discrete actions)
    tolerance: float  # a box's allowed absolute difference (0: discrete, exact)

    @property
    def passed(self) -> bool:
        """Every action agreed."""
        return self.agreeing == self.observations

    def describe(self) -> str:
        """One line for a person."""
        verdict = "passed" if self.passed else "FAILED"
        agree = f"onnxruntime's actions equal fleetrl's on {self.agreeing} of {self.observations}"
        if self.tolerance > 0:
            how = f"max difference {self.max_difference:.2g}, tolerance {self.tolerance:.2g}"
        else:
            how = "action indices, exact"
        return f"check {verdict}: {agree} observations ({how})"


def export_policy(
    model: Path,
    out: Path,
    env: str,
    *,
    observations: int = CHECK_OBSERVATIONS,
    seed: int = 0,
    unit: int = 0,
    fleet_seed: int = 0,
    fleet_profile: str | None = None,
) -> ExportCheck:
    """Write ``model``'s greedy policy to ``out`` as ONNX and check it on ``observations`` observations of
    ``unit`` of fleet ``fleet_seed`` of ``env``; a file that fails the check is not left at ``out``. A
    FileNotFoundError for no model file, a ValueError for a model not for ``env`` or a bad setting."""
    if observations < 1:
        raise ValueError(f"--check must be at least 1 observation, got {observations}")
    if out.suffix != ".onnx":
        raise ValueError(f"--out {out}: name the file .onnx")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"--out {out}: no directory {out.parent}")
    policy = read_policy_file(model)
    check_fits(policy.obs_dim, policy.action_space, describe_env(env, policy.last_step), env, model)
    graph = policy_graph(policy, env)
    partial = out.with_name(out.name + ".partial")
    partial.write_bytes(graph.SerializeToString())
    try:
        drawn = draw_observations(env, policy, observations, seed, unit, fleet_seed, fleet_profile)
        check = compare(ModelPolicy(policy), OnnxPolicy(partial), drawn)
        if check.passed:
            partial.replace(out)
        return check
    finally:
        partial.unlink(missing_ok=True)


def compare(reference: ModelPolicy, exported: OnnxPolicy, observations: np.ndarray) -> ExportCheck:
    """The exported policy's actions on ``observations`` against the reference's, one by one."""
    ours = np.stack([np.asarray(reference.act(obs)) for obs in observations])
    theirs = exported.act_batch(observations)
    if reference.action_space.is_discrete:
        agreeing = int(np.sum(ours == theirs.reshape(ours.shape)))
        return ExportCheck(len(observations), agreeing, 0.0, 0.0)
    tolerance = RELATIVE_TOLERANCE * float(np.max(reference.action_space.half_range()))
    difference = np.abs(ours.astype(np.float64) - theirs.reshape(ours.shape)).max(axis=1)
    agreeing = int(np.sum(difference <= tolerance))
    return ExportCheck(len(observations), agreeing, float(difference.max()), tolerance)


def draw_observations(
    env: str,
    policy: PolicyFile,
    n: int,
    seed: int = 0,
    unit: int = 0,
    fleet_seed: int = 0,
    fleet_profile: str | None = None,
) -> np.ndarray:
    """``n`` float32 observations: half visited under the policy's sampled actions, half drawn around them."""
    rng = np.random.default_rng(seed)
    built = get_env_spec(env).make(unit, fleet_seed, fleet_profile=fleet_profile, last_step=policy.last_step)
    gym_env, acting, space = built.env, policy.numpy_policy(), policy.action_space
    visited: list[np.ndarray] = []
    budget, episode = STEPS_PER_OBSERVATION * n, 0
    try:
        while len(visited) < budget:
            obs, _ = gym_env.reset(seed=seed + episode)
            episode += 1
            for _ in range(n):  # a mature policy's episode is long: several episodes, several resets
                visited.append(np.array(obs, dtype=np.float32))
                if space.is_discrete:
                    action: Any = acting.act(obs, float(rng.random()))
                else:
                    action = space.clip(acting.act_continuous(obs, rng.standard_normal(space.dim)))
                obs, _, terminated, truncated, _ = gym_env.step(action)
                if terminated or truncated:
                    break
            visited.append(np.array(obs, dtype=np.float32))
    finally:
        gym_env.close()
    states = np.stack(visited)
    on_path = states[rng.choice(len(states), size=n - n // 2, replace=False)]
    low, high = states.min(axis=0), states.max(axis=0)
    span = np.maximum(high - low, 1e-3)
    low, high = low - span / 2, high + span / 2
    box = gym_env.observation_space
    bounds_low = np.asarray(getattr(box, "low", low), dtype=np.float64)
    bounds_high = np.asarray(getattr(box, "high", high), dtype=np.float64)
    low = np.where(np.isfinite(bounds_low), np.maximum(low, bounds_low), low)
    high = np.where(np.isfinite(bounds_high), np.minimum(high, bounds_high), high)
    around = rng.uniform(low, high, size=(n // 2, states.shape[1]))
    return np.concatenate([on_path, around]).astype(np.float32)
