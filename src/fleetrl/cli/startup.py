"""What a command does to start sooner."""

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused(*, freeze: bool = True) -> Iterator[None]:
    """Python's cyclic garbage collector off while a command starts (it would rescan the growing heap of
    imported modules, ``docs/benchmarks.md``); on leaving, with ``freeze`` what exists is frozen
    (``gc.freeze``: never collected, so a step that leaves garbage, like parsing, passes False) and the
    collector runs again. A collector already off stays off."""
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
