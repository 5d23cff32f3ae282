"""Chief and worker state machines (Algorithms 1 and 2), aggregation, and the wire format."""
