"""The gap diagnosis's fits side by side: the candidate fits of a forward-selection step are
independent, so they run in a pool of worker processes (docs/gap.md, "Time").

    with FitPool(probe, workers=2) as pool:
        fits = pool.map([FitJob(("saturation",), tr_sub, test=te_sel), ...])

Each worker holds the probe (sent once, when it starts) and fits one job at a time. Every fit, in a
worker or in this process, runs with its BLAS on one thread (``one_blas_thread``): the numerics
are then the same bits whatever the machine's core count and whatever the number of workers, so
``pmsm-hil gap --workers 1`` and ``--workers 2`` print the same diagnosis (tested). With
``workers <= 1`` there is no pool: the jobs run here, one after another.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
import tempfile
import time
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from threadpoolctl import threadpool_limits

from pmsm_hil.gap.fit import Fit, fit_effects, set_worker_probe, worker_probe

if TYPE_CHECKING:
    from pmsm_hil.gap.probe import Probe

__all__ = ["FitJob", "FitPool", "Pending", "one_blas_thread"]


def one_blas_thread() -> AbstractContextManager[Any]:
    """BLAS (numpy's and scipy's) on one thread while the context lasts: a fit's sums are then
    split the same way on any machine (several threads split a matrix product by core count, and
    the last bits of a fit move with it)."""
    return threadpool_limits(1, user_api="blas")


@dataclass(frozen=True)
class FitJob:
    """One least-squares fit of ``names`` on the transitions ``sel`` (see fit_effects); with
    ``test``, also the fitted model's residual on those transitions."""

    names: tuple[str, ...]
    sel: np.ndarray
    max_nfev: int = 60
    warm: dict = field(default_factory=dict)
    blocks: np.ndarray | None = None
    test: np.ndarray | None = None


def run_job(probe: Probe, job: FitJob) -> tuple[Fit, np.ndarray | None]:
    """The job's fit, and its residual on ``job.test`` (None when no test is asked for or the fit
    failed)."""
    f = fit_effects(
        probe, job.names, job.sel, warm=job.warm, blocks=job.blocks, max_nfev=job.max_nfev
    )
    r = None
    if job.test is not None and np.isfinite(f.cost):
        r = probe.residual(f.effects(), job.test)
    return f, r


def _start_worker(probe_file: str) -> None:
    # Ctrl-C goes to the whole process group: the diagnosing process stops the pool
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with open(probe_file, "rb") as f:
            set_worker_probe(pickle.load(f))
    except FileNotFoundError:  # the pool was closed (Ctrl-C) while this process still started
        return  # its folder is gone; no job will come, and a traceback would only alarm
    threadpool_limits(1, user_api="blas")


def _timed(probe: Probe, job: FitJob) -> tuple[Fit, np.ndarray | None, float]:
    t0 = time.perf_counter()
    f, r = run_job(probe, job)
    return f, r, time.perf_counter() - t0


def _work(job: FitJob) -> tuple[Fit, np.ndarray | None, float]:
    return _timed(worker_probe(), job)


class Pending:
    """A submitted job: ``result()`` waits for it (its fit and test residual)."""

    def __init__(self, task: Future[tuple[Fit, np.ndarray | None, float]]):
        self.task = task

    def result(self) -> tuple[Fit, np.ndarray | None]:
        f, r, _ = self.task.result()
        return f, r


class FitPool:
    """``workers`` processes for the fits (a context manager; ``workers <= 1``: none)."""

    def __init__(self, probe: Probe, workers: int = 1):
        self.probe = probe
        self.workers = max(int(workers), 1)
        self.seconds: list[float] = []  # each job's time in the last map()
        self._ex: ProcessPoolExecutor | None = None
        self._dir: tempfile.TemporaryDirectory[str] | None = None
        if self.workers > 1:
            # The probe goes to the workers through a file: handed over as the initializer's
            # argument it would fill the pipe to a child that is still importing numpy, and this
            # process would wait for it (1.4 s on a 2 s record)
            self._dir = tempfile.TemporaryDirectory(prefix="pmsm-hil-gap-")
            path = os.path.join(self._dir.name, "probe.pickle")
            with open(path, "wb") as f:
                pickle.dump(probe, f, protocol=pickle.HIGHEST_PROTOCOL)
            # spawn, not fork: the diagnosing process may hold threads (a status line, a live
            # view), and a forked child would inherit their locks
            self._ex = ProcessPoolExecutor(
                self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_start_worker,
                initargs=(path,),
            )
            # start them now: they load while the base residuals run. SIGINT is blocked while
            # they are made, and a child keeps its parent's mask: a Ctrl-C that came while one
            # was still importing raised KeyboardInterrupt there, with a traceback on the
            # terminal, before its initializer could ignore it (here it waits, and comes on)
            old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
            try:
                for _ in range(self.workers):
                    self._ex.submit(int)
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)

    def __enter__(self) -> FitPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close(cancel=exc[0] is not None)

    def close(self, cancel: bool = False) -> None:
        if self._ex is not None:
            self._ex.shutdown(wait=not cancel, cancel_futures=cancel)
            self._ex = None
        if self._dir is not None:
            self._dir.cleanup()
            self._dir = None

    def columns(self) -> Callable | None:
        """A map-like callable over the workers, for a fit's Jacobian columns in this process
        (``fit_effects(workers=...)``); None without a pool."""
        if self._ex is None:
            return None
        ex, n = self._ex, self.workers

        def columns(fn: Callable, items: Iterable) -> list:
            # one chunk per worker, the columns dealt out in turn (neighbouring columns cost alike:
            # a model parameter's reuse the applied voltage, an inverter's do not), so that ``fn``
            # and its transitions travel once per worker, not once per column
            xs = list(items)
            order = [j for w in range(n) for j in range(w, len(xs), n)]
            size = -(-len(xs) // n)
            dealt = list(ex.map(fn, [xs[j] for j in order], chunksize=size))
            out: list = [None] * len(xs)
            for j, r in zip(order, dealt, strict=True):
                out[j] = r
            return out

        return columns

    def submit(self, job: FitJob) -> Pending:
        """Start ``job`` in a worker (without a pool: run it now)."""
        if self._ex is not None:
            return Pending(self._ex.submit(_work, job))
        done: Future[tuple[Fit, np.ndarray | None, float]] = Future()
        with one_blas_thread():
            done.set_result(_timed(self.probe, job))
        return Pending(done)

    def map(
        self,
        jobs: list[FitJob],
        done: Callable[[int, int], None] | None = None,
        cost: list[float] | None = None,
    ) -> list[tuple[Fit, np.ndarray | None]]:
        """The jobs' results in the order of ``jobs``; ``done(j, n_done)`` after each job ends
        (in the order they end). ``cost``: each job's expected time, to start the longest first
        (the step ends sooner; the results do not depend on it). ``seconds`` then holds each
        job's time."""
        out: dict[int, tuple[Fit, np.ndarray | None, float]] = {}
        if self._ex is None:  # here, one after another
            with one_blas_thread():
                for j, job in enumerate(jobs):
                    out[j] = _timed(self.probe, job)
                    if done is not None:
                        done(j, j + 1)
        else:
            order = sorted(range(len(jobs)), key=lambda j: -cost[j]) if cost else range(len(jobs))
            futures = {self._ex.submit(_work, jobs[j]): j for j in order}
            for n, fut in enumerate(as_completed(futures)):
                out[futures[fut]] = fut.result()
                if done is not None:
                    done(futures[fut], n + 1)
        self.seconds = [out[j][2] for j in range(len(jobs))]
        return [out[j][:2] for j in range(len(jobs))]
