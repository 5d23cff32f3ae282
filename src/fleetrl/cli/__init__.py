"""The ``fleetrl`` command line: the commands (``main``), the roles of a run spread over machines (``roles``),
``device`` (``device_command``), the commands on a model file (``control_command``), the flags made from the
settings classes (``settings_args``), and a quicker start (``startup``)."""
