"""Real-time pacing for device bridges and drivers: a precise sleep, and the SCHED_FIFO policy for a bridge
process."""

from __future__ import annotations

import logging
import os
import time

log = logging.getLogger(__name__)

SPIN_SECONDS = 0.0005  # ``precise_sleep_until`` sleeps until this close to the deadline, then spins


def precise_sleep_until(deadline: float) -> None:
    """Sleep until ``time.perf_counter() >= deadline``: the OS sleeps most of it, a spin does the last bit."""
    while True:
        remaining = deadline - time.perf_counter()
        if remaining <= 0.0:
            return
        if remaining > SPIN_SECONDS:
            time.sleep(remaining - SPIN_SECONDS)


def request_realtime_priority(priority: int = 10) -> bool:
    """Put this process under SCHED_FIFO at ``priority`` (as ``chrt -f``; threads started later inherit it);
    False (logged) where not permitted (it needs root or CAP_SYS_NICE)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as err:
        log.warning("no real-time priority (%s); ticks may jitter under load", err)
        return False
    log.info("real-time priority SCHED_FIFO %d", priority)
    return True
