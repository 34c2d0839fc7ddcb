"""The end of an interrupted sweep (Ctrl-C, SIGTERM or SIGHUP to the sweep's process): its runs in
progress stop the motor and keep their logs, as `pmsm-hil run` does, before the cluster closes.

The workers never see the signal (they ignore SIGINT, and a run executes in a worker's thread), so
the sweep sets a Dask event named for it (``distributed.Event``, on the scheduler, so a cluster's
remote workers hear it too); each run polls it while it streams (RunOptions.stop_requested) and,
when set, stops its device under control, closes its log and returns a row with status
"interrupted". The runs not yet started are cancelled. The sweep waits for the runs in progress at
most WAIT_S; a second interrupt closes the cluster at once, which leaves a run's log unfinalised
with its journal (`pmsm-hil log recover`).
"""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Callable, Iterator
from typing import Any

__all__ = ["NOT_STARTED", "STOP_WHY", "WAIT_S", "event_name", "stop_request", "wind_down"]

WAIT_S = 15.0  # for the runs in progress to stop their device and close their log
STOP_WHY = "the sweep's interrupt"
NOT_STARTED = "interrupted: the sweep was interrupted before this run began"


def event_name() -> str:
    """A new sweep's stop event (unique on a shared scheduler)."""
    return f"pmsm-hil-stop-{uuid.uuid4().hex}"


def stop_request(name: str | None) -> Callable[[], str] | None:
    """In a Dask worker: a poll of the sweep's stop event (STOP_WHY once set, else ""); None
    outside a worker or without an event (a run of `pmsm-hil test` in its own process stops on
    its own signals)."""
    if not name:
        return None
    try:
        from distributed import Event, get_worker

        get_worker()
    except (ImportError, ValueError):  # not in a worker
        return None
    event = Event(name)

    def requested() -> str:
        try:
            return STOP_WHY if event.is_set() else ""
        except Exception:  # the scheduler has gone: the sweep is closing
            return STOP_WHY

    return requested


def wind_down(client: Any, futures: list[Any], name: str) -> Iterator[Any]:
    """After the sweep's interrupt: set its stop event, cancel the runs not started, and yield
    the futures that end (those finished before the interrupt included) within WAIT_S. A second
    interrupt (KeyboardInterrupt) or the wait's end stops the yield."""
    from distributed import Event, as_completed

    Event(name, client=client).set()
    busy = {k for keys in client.processing().values() for k in keys}
    left = [f for f in futures if f.done() or f.key in busy]
    idle = [f for f in futures if not f.done() and f.key not in busy]
    if idle:  # done once cancelled: after ``left`` is taken
        client.cancel(idle)
    with contextlib.suppress(TimeoutError):
        yield from as_completed(left, timeout=WAIT_S)
