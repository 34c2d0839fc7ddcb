"""Dask preload for the local cluster's worker processes (sweep/driver.py): they ignore SIGINT.
A Ctrl-C in the terminal reaches the whole process group; the sweep's own process handles it
(summary, exit 130) and closes the cluster, which stops the workers. Without this each worker
printed its KeyboardInterrupt traceback under the sweep's summary. A worker started while the
sweep held SIGINT blocked (driver._sigint_held) inherited the mask: a Ctrl-C of that moment waits
pending, and is discarded here when SIGINT becomes ignored, before it is unblocked."""

from __future__ import annotations

import signal
import threading
from typing import Any


def dask_setup(worker: Any) -> None:
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if hasattr(signal, "pthread_sigmask"):
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
