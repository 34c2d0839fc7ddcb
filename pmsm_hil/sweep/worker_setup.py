"""Dask preload for the local cluster's worker processes (sweep/driver.py): they ignore SIGINT,
and say nothing when the scheduler has gone.
A Ctrl-C in the terminal reaches the whole process group; the sweep's own process handles it
(summary, exit 130) and closes the cluster, which stops the workers. Without this each worker
printed its KeyboardInterrupt traceback under the sweep's summary. A worker started while the
sweep held SIGINT, SIGTERM and SIGHUP blocked (driver._interrupts_held) inherited the mask: a
Ctrl-C of that moment waits pending, and is discarded here when SIGINT becomes ignored, before it
is unblocked; SIGTERM and SIGHUP are unblocked at their default (a worker is stopped with them).

The local cluster's scheduler lives in the sweep's own process: when a worker finds it gone, the
sweep is closing (a Ctrl-C while the worker was busy with a run closes the scheduler before the
worker hears of it). Distributed then logs the worker's failed heartbeat as an error with two
tracebacks, which reached the terminal under the sweep's summary (seen in CI under load); those
records are dropped (SchedulerGone)."""

from __future__ import annotations

import logging
import signal
import threading
from typing import Any

from pmsm_hil.log.write_support import HELD_SIGNALS


class SchedulerGone(logging.Filter):
    """Drops the worker's records of a connection to the scheduler found closed."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        return type(exc).__name__ not in ("CommClosedError", "StreamClosedError")


def dask_setup(worker: Any) -> None:
    logging.getLogger("distributed.worker").addFilter(SchedulerGone())
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if hasattr(signal, "pthread_sigmask"):
            signal.pthread_sigmask(signal.SIG_UNBLOCK, HELD_SIGNALS)
