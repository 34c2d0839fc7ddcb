"""A sweep on Dask (dask.distributed): a LocalCluster of one single-threaded worker process per
core by default, or any scheduler given by address. Each run is one task (``execute_run``); a task
whose worker dies is run once more elsewhere (the scheduler's ``allowed-failures`` = 1) and then
reported failed with the error. Finished runs go to the journal as they come back, so an
interrupted sweep resumes where it stopped.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pmsm_hil.log.write_support import HELD_SIGNALS

from .execute import execute_run
from .plan import FILES, Run, plan_runs
from .results import Journal, check_resumable, check_same_sweep, passed, write_meta, write_table
from .spec import Sweep
from .wind_down import NOT_STARTED, event_name, wind_down

__all__ = [
    "ALLOWED_FAILURES",
    "SCHEDULER_CONFIG",
    "SweepOutcome",
    "run_runs",
    "run_sweep",
    "write_inputs",
]

ALLOWED_FAILURES = 1  # a task is re-run once after its worker died, then reported failed
# and a worker holds only the run it executes (no queued second run that its death would also
# count against): the scheduler's settings for a local cluster, and what a cluster's scheduler
# should be started with (docs/sweep.md)
SCHEDULER_TIMEOUT_S = 10.0  # to reach a scheduler given by address
SCHEDULER_CONFIG = {
    "distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
    "distributed.scheduler.worker-saturation": 1.0,
}


@dataclass
class SweepOutcome:
    """What a sweep did. ``ok``/``failed``: runs of this call that completed / could not be run
    (a completed run may still miss the profile's acceptance criteria: ``met``)."""

    out: Path
    planned: int
    skipped: int = 0  # done in an earlier, interrupted sweep
    ok: int = 0
    failed: int = 0
    stopped: int = 0  # runs in progress when the sweep was interrupted: stopped, logs kept
    interrupted: bool = False
    wall_s: float = 0.0
    rows: list[dict[str, Any]] = field(default_factory=list)
    parquet: Path | None = None
    csv: Path | None = None
    workers: int = 0
    criteria: bool = False  # the profile has acceptance criteria

    @property
    def runs_per_min(self) -> float:
        n = self.ok + self.failed
        return 60.0 * n / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def completed(self) -> int:
        """Rows of the table (this call's and those done before) whose run completed."""
        return sum(1 for r in self.rows if r.get("status") == "ok")

    @property
    def met(self) -> int:
        """Rows that completed, whole and without a fault, within the acceptance criteria."""
        return sum(1 for r in self.rows if passed(r))

    def end_lines(self) -> list[str]:
        """The sweep's last words: what ran (completed / failed to run: an ok run is not a
        pass), then how many completed runs met the profile's acceptance criteria."""
        n = self.ok + self.failed
        lines = [
            f"runs: {self.ok} completed, {self.failed} failed to run, {self.skipped} done before"
            + (f", {self.stopped} stopped by the interrupt" if self.stopped else "")
            + (
                f"; {self.runs_per_min:.1f} runs/min on {self.workers} "
                f"worker{'s' if self.workers != 1 else ''}"
                if n
                else ""
            )
            + (" (interrupted: run the same command again to resume)" if self.interrupted else "")
        ]
        report = f"`pmsm-hil sweep report {self.out}`"
        if self.criteria:
            lines.append(
                f"acceptance criteria: met by {self.met} of the {self.completed} completed runs, "
                f"missed by {self.completed - self.met}"
                + (f" ({report} for the metrics)" if self.completed - self.met else "")
            )
        else:
            lines.append(
                f"acceptance criteria: none in the profile, nothing judged ({self.met} of the "
                f"{self.completed} completed runs played it whole without a fault)"
            )
        return lines


def write_inputs(out: Path, run: Run) -> Path:
    """OUT/runs/KEY/: the run's profile, motor and rig files and its seed, to re-run it alone with
    `pmsm-hil run OUT/runs/KEY/profile.yaml --seed SEED`."""
    d = Path(out) / "runs" / run.key
    d.mkdir(parents=True, exist_ok=True)
    for name in FILES:
        p = d / name
        if not p.exists() or p.read_text(encoding="utf-8") != run.texts[name]:
            p.write_text(run.texts[name], encoding="utf-8")
    (d / "run.json").write_text(
        json.dumps({"seed": run.seed, "values": run.values}, sort_keys=True) + "\n"
    )
    return d


class SyncCancelRace(logging.Filter):
    """Drops one record: dask.distributed's ``sync()`` schedules a cancel when Ctrl-C reaches the
    calling thread, and if its call has not started yet the cancel raises NameError ('future'
    not bound), which tornado logs as an error with a traceback under the sweep's summary.
    Nothing had started, so nothing is lost; every other record passes."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        return not (isinstance(exc, NameError) and "'future'" in str(exc))


@contextlib.contextmanager
def _interrupts_held() -> Iterator[None]:
    """SIGINT (and SIGTERM, SIGHUP, which the CLI takes as a Ctrl-C) blocked in this thread while
    the local cluster starts: the threads and worker processes started meanwhile inherit the mask,
    so a terminal's Ctrl-C in that second stays pending in each worker until its preload
    (sweep/worker_setup.py) ignores it, instead of
    printing the worker's KeyboardInterrupt traceback under the summary. Here it is delivered when
    the mask is restored, once the client and the cluster are assigned (and so closed)."""
    if not hasattr(signal, "pthread_sigmask") or (
        threading.current_thread() is not threading.main_thread()
    ):
        yield
        return
    # multiprocessing's resource tracker, started on demand from the cluster's loop thread,
    # unblocks SIGINT there after spawning itself (SIG_UNBLOCK, not the mask it found): start it
    # first, here, so that the thread that spawns the workers keeps the mask
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _client(scheduler: str | None, workers: int | None):
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        _probe(scheduler)
        client = Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S:g}s")
        if not client.scheduler_info().get("workers"):
            # dask waits for one silently: say why nothing moves
            print(
                f"{scheduler}: the scheduler has no workers yet; the runs start when one joins "
                f"(e.g. `dask worker {scheduler}`)",
                file=sys.stderr,
            )
        return client, None
    dask.config.set(SCHEDULER_CONFIG)
    cluster = LocalCluster(
        n_workers=workers or os.cpu_count() or 1,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        # the scheduler's HTTP server (health, metrics; no dashboard) on a free port: Dask's
        # default, 8787, is taken when a cluster runs on the machine, and Dask then warns
        dashboard_address="127.0.0.1:0",
        scheduler_kwargs={"dashboard": False},
        silence_logs=logging.ERROR,
        preload=["pmsm_hil.sweep.worker_setup"],  # the workers ignore the terminal's Ctrl-C
    )
    return Client(cluster), cluster


def _probe(address: str, timeout_s: float = SCHEDULER_TIMEOUT_S) -> None:
    """Connect to ``address`` and take its Dask handshake, else OSError: Dask's own when nothing
    takes the connection within ``timeout_s``, ours when a server takes it and says nothing for a
    second longer (the scheduler's HTTP dashboard, tcp://HOST:8787, given for the scheduler: Dask's
    client waits for its handshake without end)."""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from distributed.comm import connect
    from distributed.security import Security

    async def handshake() -> None:
        args = Security().get_connection_args("client")
        comm = await asyncio.wait_for(connect(address, timeout=timeout_s, **args), timeout_s + 1)
        await comm.close()

    try:  # in a thread of its own: a caller may be inside an event loop (a notebook)
        with ThreadPoolExecutor(1) as pool:
            pool.submit(asyncio.run, handshake()).result()
    except TimeoutError:  # asyncio's, from wait_for: the connection was taken, nothing answered
        raise OSError(
            f"something took the connection but did not answer as a Dask scheduler in "
            f"{timeout_s + 1:g} s"
        ) from None


def _error_of(exc: BaseException) -> str:
    from distributed.scheduler import KilledWorker

    if isinstance(exc, KilledWorker):
        return f"the worker died running it, twice ({ALLOWED_FAILURES + 1} attempts): {exc}"
    return f"{type(exc).__name__}: {exc}"


def run_sweep(
    sweep: Sweep,
    out: Path,
    *,
    limit: int | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    task_fn: Callable[[dict], dict] = execute_run,
    runs: list[Run] | None = None,
) -> SweepOutcome:
    """Run the sweep (its first ``limit`` runs) into ``out``; skip the runs done there before.
    Raises ResultsFormatError when ``out`` holds an older pmsm-hil's results or another sweep's."""
    out = Path(out)
    check_resumable(out)
    check_same_sweep(out, sweep.name)
    out.mkdir(parents=True, exist_ok=True)
    runs = plan_runs(sweep) if runs is None else runs
    if limit is not None:
        runs = runs[:limit]
    write_meta(out, sweep.name, str(sweep.path), str(sweep.profile_path), sweep.axes)
    return run_runs(
        runs,
        out,
        list(sweep.spec.metrics),
        keep_logs=sweep.spec.keep_logs,
        axes=[c for a in sweep.axes for c in a.columns],
        scheduler=scheduler,
        workers=workers,
        progress=progress,
        task_fn=task_fn,
    )


def run_runs(
    runs: list[Run],
    out: Path,
    metrics: list[str],
    *,
    keep_logs: bool = False,
    axes: list[str] | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    task_fn: Callable[[dict], dict] = execute_run,
    label: str = "sweep",
) -> SweepOutcome:
    """Run ``runs`` on Dask into ``out`` (the machinery of a sweep, also for `pmsm-hil test`,
    whose progress bar is labelled ``label``). The table's rows take their index, seed and axis
    columns from ``runs`` (the key is a hash of the inputs, so a journalled row of the same key
    is the same run, whatever an older pmsm-hil named its columns)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    axes = list(axes or [])
    journal = Journal(out)
    done = journal.done()
    todo = [r for r in runs if r.key not in done]
    res = SweepOutcome(
        out=out, planned=len(runs), skipped=len(runs) - len(todo), criteria=_has_criteria(runs)
    )
    by_key = {r.key: r for r in runs}
    t0 = time.perf_counter()
    client = cluster = None
    quiet = SyncCancelRace()
    futures: list[Any] = []
    taken: set[str] = set()  # the futures whose row is in the journal
    stop_event = event_name()

    def take(fut: Any) -> dict[str, Any]:
        """A finished run's row, into the journal (a run that never began: not kept) and the
        counts."""
        run = by_key[fut.key[len("pmsm-run-") :]]
        try:
            row = fut.result()
        except Exception as e:
            row = {"key": run.key, "status": "failed", "error": _error_of(e), "log_path": ""}
        fut.release()
        row = result_row(row, run)
        taken.add(fut.key)
        if row.get("error") == NOT_STARTED:
            return row
        journal.add(row)
        if row["status"] == "ok":
            res.ok += 1
        elif row["status"] == "interrupted":
            res.stopped += 1
        else:
            res.failed += 1
        return row

    missed = sum(
        1 for r in runs if r.key in done and not passed(result_row(journal.rows[r.key], r))
    )
    try:  # from here on a Ctrl-C ends with the summary and the table (the inputs' writing, the
        # imports and the cluster's start take a second or more)
        for r in runs:
            write_inputs(out, r)
        from distributed import as_completed

        bar = _Bar(
            len(runs),
            res.skipped,
            enabled=progress,
            label=label,
            missed=missed if res.criteria else None,
        )
        if todo:
            with _interrupts_held():
                client, cluster = _client(scheduler, workers)
            res.workers = len(client.scheduler_info().get("workers", {}))
            for r in todo:
                log = str((out / "logs" / f"{r.key}.mcap").resolve()) if keep_logs else None
                task = {**r.task(metrics, log), "stop_event": stop_event}
                futures.append(client.submit(task_fn, task, key=f"pmsm-run-{r.key}", pure=False))
            with bar:
                for fut in as_completed(futures):
                    row = take(fut)
                    bar.advance(row["status"] == "ok", time.perf_counter() - t0, met=passed(row))
    except KeyboardInterrupt:
        res.interrupted = True
        logging.getLogger("tornado.application").addFilter(quiet)  # until both are closed
        if client is not None and futures:  # the runs in progress stop their motor, keep their log
            if progress:
                print(
                    "interrupted: stopping the runs in progress, their logs kept "
                    "(Ctrl-C again to close at once)",
                    file=sys.stderr,
                    flush=True,
                )
            # a second interrupt, or a scheduler that has gone: close at once
            with contextlib.suppress(KeyboardInterrupt, Exception):
                for fut in wind_down(
                    client, [f for f in futures if f.key not in taken], stop_event
                ):
                    take(fut)
    finally:
        res.wall_s = time.perf_counter() - t0
        if client is not None:
            # a cluster's workers may join after the start (none yet: the runs waited for one)
            with contextlib.suppress(Exception):
                res.workers = max(res.workers, len(client.scheduler_info().get("workers", {})))
            client.close()
        if cluster is not None:
            cluster.close()
        logging.getLogger("tornado.application").removeFilter(quiet)
        res.rows = [result_row(journal.rows[r.key], r) for r in runs if r.key in journal.rows]
        res.parquet, res.csv = write_table(out, res.rows, axes)
    return res


_PLAN_COLUMNS = ("index", "key", "seed")


def result_row(result: dict[str, Any], run: Run) -> dict[str, Any]:
    """A run's row: its index, key, seed and axis columns (from the plan), then its results."""
    return {
        "index": run.index,
        "key": run.key,
        "seed": run.seed,
        **run.values,
        **{k: v for k, v in result.items() if k not in run.values and k not in _PLAN_COLUMNS},
    }


def _has_criteria(runs: list[Run]) -> bool:
    """Whether the runs' profile has acceptance criteria (the first run's: a sweep's runs share
    the profile, and an axis cannot add or remove the section)."""
    import yaml

    return bool(runs) and bool(
        (yaml.safe_load(runs[0].texts["profile.yaml"]) or {}).get("acceptance")
    )


PLAIN_EVERY_S = 5.0  # without a terminal: a progress line at most this often (and the last run's)


class _Bar:
    """rich progress: runs done (and skipped), failed to run, runs per minute, time left; with
    ``missed`` (the count so far: the profile has acceptance criteria) the completed runs that
    missed them, so that a run done is not read as a run passed. On a terminal too narrow for all
    of it on one line (80 columns) the counts go on a second line, rather than rich cutting the
    numbers short ("12…"). Without a terminal (a CI log, a pipe) the same in a plain line as runs
    finish, at most one each PLAIN_EVERY_S and the last (rich would print its bar once, at the
    end: a long sweep in CI showed nothing for minutes)."""

    def __init__(
        self,
        total: int,
        skipped: int,
        enabled: bool,
        label: str = "sweep",
        unit: str = "runs",
        missed: int | None = None,
    ):
        self.unit = unit
        self.enabled = enabled
        self.total, self.done, self.failed = total, skipped, 0
        self.missed = missed
        self.new = 0
        self.label = label
        self.plain = False  # no terminal: plain lines (_say), the rich bar not shown
        self._said_s, self._said_done, self._elapsed_s = -PLAIN_EVERY_S, skipped, 0.0
        if enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )
            from rich.text import Text

            counts = [("failed", "failed to run")]  # task field, its words
            if missed is not None:
                counts.append(("missed", "missed the criteria"))
            console = Console()
            self.plain = not console.is_terminal
            if not console.is_terminal:  # a CI log: the final line whole, not cut at 80 columns
                console = Console(width=max(console.width, 160))
            # the widest the one line gets (every count as large as the total), with a bar of 10
            n = "9" * len(str(total))
            widest = " ".join(
                [label, f"{n}/{n} {unit} done"]
                + [f"{n} {words}" for _, words in counts]
                + [f"9999.9 {unit}/min", "0:00:00"]
            )
            one_line = console.width >= len(widest) + 11

            class _Progress(Progress):
                def get_renderables(self):
                    yield self.make_tasks_table(self.tasks)
                    if not one_line:  # the counts on a line of their own
                        for task in self.tasks:
                            said = [f"{task.fields[k]} {words}" for k, words in counts]
                            yield Text("  " + ", ".join(said))

            self.progress = _Progress(
                TextColumn(label),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn(f"{unit} done"),
                *(
                    [TextColumn(f"{{task.fields[{k}]}} {words}") for k, words in counts]
                    if one_line
                    else []
                ),
                TextColumn("{task.fields[rate]}"),
                TimeRemainingColumn(),
                transient=False,
                console=console,
            )
            self.task = self.progress.add_task(
                label, total=total, completed=skipped, failed=0, missed=missed or 0, rate=""
            )

    def __enter__(self):
        if self.enabled and not self.plain:
            self.progress.__enter__()
        return self

    def __exit__(self, *exc):
        if self.enabled and not self.plain:
            self.progress.__exit__(*exc)
        elif self.enabled and self.done != self._said_done:  # interrupted since the last line
            self._say(self._elapsed_s)

    def _say(self, elapsed_s: float) -> None:
        """The progress as one plain line: ``sweep: 5/12 runs done, 0 failed to run, 1 missed the
        criteria; 54.4 runs/min, about 0:00:08 left``."""
        counts = [f"{self.failed} failed to run"]
        if self.missed is not None:
            counts.append(f"{self.missed} missed the criteria")
        line = f"{self.label}: {self.done}/{self.total} {self.unit} done, {', '.join(counts)}"
        if elapsed_s > 0 and self.new:
            rate = 60.0 * self.new / elapsed_s
            line += f"; {rate:.1f} {self.unit}/min"
            if self.done < self.total:
                left_s = round(60.0 * (self.total - self.done) / rate)
                line += f", about {left_s // 3600}:{left_s // 60 % 60:02d}:{left_s % 60:02d} left"
        print(line, flush=True)
        self._said_s, self._said_done = elapsed_s, self.done

    def advance(self, ok: bool, elapsed_s: float, met: bool = True) -> None:
        """One more done: ``ok`` it completed, ``met`` it met the acceptance criteria."""
        self.done += 1
        self.new += 1
        self.failed += 0 if ok else 1
        if self.missed is not None and ok and not met:
            self.missed += 1
        self._elapsed_s = elapsed_s
        if self.enabled:
            rate = 60.0 * self.new / elapsed_s if elapsed_s > 0 else 0.0
            self.progress.update(
                self.task,
                completed=self.done,
                failed=self.failed,
                missed=self.missed or 0,
                rate=f"{rate:.1f} {self.unit}/min",
            )
        due = elapsed_s - self._said_s >= PLAIN_EVERY_S or self.done == self.total
        if self.enabled and self.plain and due:
            self._say(elapsed_s)
