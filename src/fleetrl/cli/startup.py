"""What a command does to start sooner."""

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector off while a command starts (parsing, checking the settings,
    importing torch and fleetrl), where it would scan the growing heap of imported modules again and again
    (~0.4 s of CPU, ``docs/benchmarks.md``), when little of it is garbage. On leaving, even by an error,
    what exists then is frozen (``gc.freeze``: left out of later collections, and its memory shared with
    the forked worker processes) and the collector runs again. A collector already off stays off."""
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.enable()
