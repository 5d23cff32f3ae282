"""Reaching a device: in-process, or over MQTT through a device bridge, behind one interface."""
