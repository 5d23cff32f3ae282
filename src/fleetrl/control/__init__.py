"""A trained policy on its unit, without a learner, a chief or a broker: ``fleetrl export`` (ONNX) and
``fleetrl control`` (run a saved policy on one unit through its driver, with the device bridge's safety).

Its place in the layer order (docs/on-device.md): above ``agent``, ``envs`` and ``link`` (it runs a saved
actor, ``fleetrl.agent.policy_file``, on a unit's env over a link to the unit's device bridge), beside
``federation`` and below ``runs`` and ``cli``; it uses ``fleetrl.transport.local``, the in-process bus, to
reach that bridge. Nothing on the controller's path imports torch.
"""
