"""The ``fleetrl`` command line: the commands (``main``), the roles of a run spread over machines (``roles``),
``device`` (``device_command``), ``export`` and ``control`` (``control_command``), the flags made from the
settings classes (``settings_args``, ``parsing``), and a quicker start (``startup``)."""
