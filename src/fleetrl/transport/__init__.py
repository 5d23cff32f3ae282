"""Message transports: MQTT (paho), the embedded broker, and an in-process bus with the same interface."""
