"""What a command does to start sooner."""

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused(*, freeze: bool = True) -> Iterator[None]:
    """Python's cyclic garbage collector off while a command starts (parsing, checking the settings,
    importing torch and fleetrl), where it would scan the growing heap of imported modules again and again
    (~0.4 s of CPU, ``docs/benchmarks.md``), when little of it is garbage. On leaving, even by an error,
    with ``freeze`` what exists then is frozen (``gc.freeze``: left out of later collections, and its memory
    shared with the forked worker processes; what was already garbage then is never freed, so a step that
    leaves garbage behind, like parsing, passes ``freeze=False``) and the collector runs again. A collector
    already off stays off."""
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        if freeze:
            gc.freeze()
        gc.enable()
