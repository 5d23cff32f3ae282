"""A unit module that cannot be imported: it needs a package that is not installed."""

import fleetrl_no_such_dependency  # type: ignore[import-not-found]  # noqa: F401


def factory(unit: int, fleet_seed: int) -> object:
    """Never reached."""
    return None
