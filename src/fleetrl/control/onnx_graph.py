"""The greedy policy of a model file as an ONNX graph (opset 17), built node by node from the actor's weights:
``observation`` (float32) in; ``action`` out, a discrete action's index (``ArgMax``, the first on a tie) or a
box's clipped Gaussian mean. The model's ``fleetrl`` metadata names the observation size, the action space
and the env (docs/on-device.md). Needs the ``onnx`` package (the ``export`` extra).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from fleetrl.agent.policy_file import PolicyFile

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
    """The greedy policy of ``policy`` as an ``onnx.ModelProto`` (checked by ``onnx.checker``).

    :param env: the env the policy is for (recorded in the metadata; None: not known)
    """
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
