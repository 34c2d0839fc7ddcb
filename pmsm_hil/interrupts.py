"""What stops a run before its end, as the runner counts it: SIGINT, SIGTERM and SIGHUP in the
main thread, and a stop request polled from elsewhere (a sweep's worker runs in a thread, where no
signal arrives: the sweep asks its runs to stop through a Dask event, sweep/wind_down.py)."""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable
from types import FrameType
from typing import Any

__all__ = ["STOP_POLL_S", "Interrupts"]

STOP_POLL_S = 0.25  # wall time between two polls of a stop request (a round trip to a scheduler)


class Interrupts:
    """SIGINT/SIGTERM/SIGHUP during a run: counted, never raised in the middle of a log write.

    The first asks for a controlled stop, the second for an abort. Handlers are installed only in
    the main thread (Python's rule) and restored afterwards. ``requested``: polled by ``poll()``
    at most every STOP_POLL_S; a non-empty answer (why) counts as a first signal.
    """

    SIGNALS = tuple(
        s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s
    )

    def __init__(self, requested: Callable[[], str] | None = None) -> None:
        self.count = 0
        self.signal_name = ""
        self._old: dict[signal.Signals, Any] = {}
        self._requested = requested
        self._next_poll = 0.0

    def _handler(self, signum: int, _frame: FrameType | None) -> None:
        self.count += 1
        self.signal_name = signal.Signals(signum).name

    def poll(self) -> int:
        """The count, after asking ``requested`` when its time has come (a request is taken once:
        it asks for the controlled stop, never for the abort)."""
        if self._requested is not None and not self.count:
            now = time.monotonic()
            if now >= self._next_poll:
                self._next_poll = now + STOP_POLL_S
                why = self._requested()
                if why:
                    self.count, self.signal_name = 1, why
        return self.count

    def __enter__(self) -> Interrupts:
        if threading.current_thread() is threading.main_thread():
            for s in self.SIGNALS:
                self._old[s] = signal.signal(s, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        for s, old in self._old.items():
            signal.signal(s, old)
