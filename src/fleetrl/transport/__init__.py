"""Message transports behind one interface (``base``): MQTT over paho (``mqtt``, its password in ``login``),
the embedded broker (``broker``, amqtt's faults mended in ``amqtt_mended``), an in-process bus (``local``),
and a unit's slow (``delayed``) or stalling (``stalled``) uplink. Nothing about RL."""
