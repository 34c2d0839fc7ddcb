"""A sweep on Dask (dask.distributed): a LocalCluster of one single-threaded worker process per
core by default, or any scheduler given by address. Each run is one task (``execute_run``); a task
whose worker dies is run once more elsewhere (the scheduler's ``allowed-failures`` = 1) and then
reported failed with the error. Finished runs go to the journal as they come back, so an
interrupted sweep resumes where it stopped.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .execute import execute_run
from .plan import FILES, Run, plan_runs
from .results import Journal, write_table
from .spec import Sweep

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
SCHEDULER_CONFIG = {
    "distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
    "distributed.scheduler.worker-saturation": 1.0,
}


@dataclass
class SweepOutcome:
    out: Path
    planned: int
    skipped: int = 0  # done in an earlier, interrupted sweep
    ok: int = 0
    failed: int = 0
    interrupted: bool = False
    wall_s: float = 0.0
    rows: list[dict[str, Any]] = field(default_factory=list)
    parquet: Path | None = None
    csv: Path | None = None
    workers: int = 0

    @property
    def runs_per_min(self) -> float:
        n = self.ok + self.failed
        return 60.0 * n / self.wall_s if self.wall_s > 0 else 0.0


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


def _client(scheduler: str | None, workers: int | None):
    import logging

    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        client = Client(scheduler, timeout="10s")
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
        dashboard_address=None,
        scheduler_kwargs={"dashboard": False},
        silence_logs=logging.ERROR,
    )
    return Client(cluster), cluster


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
    """Run the sweep (its first ``limit`` runs) into ``out``; skip the runs done there before."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs = plan_runs(sweep) if runs is None else runs
    if limit is not None:
        runs = runs[:limit]
    (out / "sweep.json").write_text(
        json.dumps(
            {
                "name": sweep.name,
                "file": str(sweep.path),
                "profile": str(sweep.profile_path),
                "axes": [
                    {"name": a.name, "field": a.field, "kind": a.kind, "relative": a.relative}
                    for a in sweep.axes
                ],
            },
            indent=1,
        )
        + "\n"
    )
    return run_runs(
        runs,
        out,
        list(sweep.spec.metrics),
        keep_logs=sweep.spec.keep_logs,
        axes=[a.name for a in sweep.axes],
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
) -> SweepOutcome:
    """Run ``runs`` on Dask into ``out`` (the machinery of a sweep, also for `pmsm-hil test`)."""
    from distributed import as_completed

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    axes = list(axes or [])
    journal = Journal(out)
    done = journal.done()
    todo = [r for r in runs if r.key not in done]
    res = SweepOutcome(out=out, planned=len(runs), skipped=len(runs) - len(todo))
    by_key = {r.key: r for r in runs}
    for r in runs:
        write_inputs(out, r)
    t0 = time.perf_counter()
    client = cluster = None
    bar = _Bar(len(runs), res.skipped, enabled=progress)
    try:
        if todo:
            client, cluster = _client(scheduler, workers)
            res.workers = len(client.scheduler_info().get("workers", {}))
            futures = []
            for r in todo:
                log = str((out / "logs" / f"{r.key}.mcap").resolve()) if keep_logs else None
                futures.append(
                    client.submit(
                        task_fn, r.task(metrics, log), key=f"pmsm-run-{r.key}", pure=False
                    )
                )
            with bar:
                for fut in as_completed(futures):
                    run = by_key[fut.key[len("pmsm-run-") :]]
                    try:
                        row = fut.result()
                    except Exception as e:
                        row = {
                            "key": run.key,
                            "status": "failed",
                            "error": _error_of(e),
                            "log_path": "",
                        }
                    fut.release()
                    row = {
                        "index": run.index,
                        "key": run.key,
                        "seed": run.seed,
                        **run.values,
                        **row,
                    }
                    journal.add(row)
                    if row["status"] == "ok":
                        res.ok += 1
                    else:
                        res.failed += 1
                    bar.advance(row["status"] == "ok", time.perf_counter() - t0)
    except KeyboardInterrupt:
        res.interrupted = True
    finally:
        res.wall_s = time.perf_counter() - t0
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
        res.rows = [journal.rows[r.key] for r in runs if r.key in journal.rows]
        res.parquet, res.csv = write_table(out, res.rows, axes)
    return res


class _Bar:
    """rich progress: runs done (and skipped), failed, runs per minute, time left."""

    def __init__(
        self, total: int, skipped: int, enabled: bool, label: str = "sweep", unit: str = "runs"
    ):
        self.unit = unit
        self.enabled = enabled
        self.total, self.done, self.failed = total, skipped, 0
        self.new = 0
        if enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )

            self.progress = Progress(
                TextColumn(label),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[failed]} failed"),
                TextColumn("{task.fields[rate]}"),
                TimeRemainingColumn(),
                transient=False,
            )
            self.task = self.progress.add_task(
                "sweep", total=total, completed=skipped, failed=0, rate=""
            )

    def __enter__(self):
        if self.enabled:
            self.progress.__enter__()
        return self

    def __exit__(self, *exc):
        if self.enabled:
            self.progress.__exit__(*exc)

    def advance(self, ok: bool, elapsed_s: float) -> None:
        self.done += 1
        self.new += 1
        self.failed += 0 if ok else 1
        if self.enabled:
            rate = 60.0 * self.new / elapsed_s if elapsed_s > 0 else 0.0
            self.progress.update(
                self.task,
                completed=self.done,
                failed=self.failed,
                rate=f"{rate:.1f} {self.unit}/min",
            )
