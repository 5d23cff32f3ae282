"""A trained policy on its unit, without a learner, a chief or a broker (docs/on-device.md): ``fleetrl
export`` writes the greedy policy as ONNX (``export``); ``fleetrl control`` runs a saved one (``policies``:
numpy or onnxruntime, no torch, and the greedy episodes ``fleetrl evaluate`` shares) on one unit through its
driver with the device bridge's safety (``controller``)."""
