"""Message transports behind one interface (``base``): MQTT over paho (``mqtt``, its password in ``login``),
the embedded broker (``broker``), an in-process bus (``local``), and a unit's slow (``delayed``) or stalling
(``stalled``) uplink. Nothing about RL."""
