"""The ``fleetrl`` command line."""
