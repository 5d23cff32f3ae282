"""The greedy policy of a model file as an ONNX graph, built node by node from the actor's weights.

The graph (opset 17, IR version 8: what onnxruntime and the common embedded runtimes load):

* input ``observation``: float32 ``(batch, obs_dim)``, the observation as the env returns it;
* the trunk: ``Gemm`` (x·Wᵀ + b) then ``Tanh`` or ``Relu`` per layer, the policy head a last ``Gemm``;
* output ``action``:
  - discrete: int64 ``(batch,)``, the **index** of the most probable action (``ArgMax`` of the logits,
    the first on a tie, as fleetrl's own argmax) — the index the env takes; what it commands on the unit
    is the unit's (the QUBE's three indices are −1.44, 0, +1.44 V: ``fleetrl.link.driver.qube_spec``);
  - a box: float32 ``(batch, dim)``, the Gaussian's mean in the env's units, ``centre + half_range·head``,
    clipped to ``[low, high]`` per component — the command itself (the QUBE's: volts).

The model's ``metadata_props`` carry ``fleetrl``: a JSON object with the format, the observation size, the
action space (``ActionSpace.to_dict``) and the env it was checked on, so ``fleetrl control`` can run the
file and check it against its unit without the model file it came from. Needs the ``onnx`` package (the
``export`` extra); running the graph needs only onnxruntime.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from fleetrl.agent.policy_file import PolicyFile

FORMAT = "fleetrl.policy/1"
"""the ``format`` in every exported file's ``fleetrl`` metadata"""
OPSET = 17
IR_VERSION = 8
INPUT = "observation"
OUTPUT = "action"


def policy_metadata(policy: PolicyFile, env: str | None) -> dict[str, Any]:
    """What an exported file records about its policy (the ``fleetrl`` metadata, as a dict)."""
    return {
        "format": FORMAT,
        "obs_dim": policy.obs_dim,
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
