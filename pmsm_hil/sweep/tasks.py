"""Any list of independent trials on the sweep's Dask machinery: a LocalCluster of one
single-threaded worker process per core (or a scheduler by address), a task re-run once when its
worker dies and then reported failed, a progress bar, and, with an output folder, a journal keyed
by each trial's inputs so that an interrupted batch resumes where it stopped. `gap selftest` and
`bench identify` run their trials here (docs/sweep.md, "Other trials on the machinery").

    results = run_tasks(fn, trials, out=Path("selftest"), name="selftest")

``fn`` takes one trial (a JSON-able dict) and returns a JSON-able dict; it runs in a worker
process, so it must be importable there (a module-level function). Every result comes back through
JSON, so a fresh result and one read from the journal are the same values. A trial that raises is
reported failed with its error (one line, no worker traceback on the terminal).

The key of a trial is a hash of its inputs and of the firmware build (``fwlib.source_id``, a hash
of the C sources the emulator was compiled from): after a firmware change nothing is taken from the
journal, and a worker whose build is not the client's fails its trials with both builds named.

Dask starts each worker process with its BLAS and OpenMP libraries on one thread (the nanny's
``pre-spawn-environ``: the variables in BLAS_THREADS set to 1), so a trial whose numerics go
through BLAS gives the same bits on any machine and cluster; in a process whose BLAS uses several
threads (the default of a plain Python process: one per core) such sums are split differently and
the last bits can differ.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .driver import _Bar, _client, _error_of, _interrupts_held
from .results import Journal

__all__ = ["BLAS_THREADS", "run_tasks", "task_key"]

BLAS_THREADS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def task_key(task: dict[str, Any], firmware: str | None = None) -> str:
    """The key of a trial: a hash of its inputs and the firmware build (the same trial on the same
    firmware, the same key); ``firmware``: the build's id when the caller has it already."""
    if firmware is None:
        from pmsm_hil.emulator.fwlib import source_id

        firmware = source_id()
    text = json.dumps({"task": task, "firmware": firmware}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


_FAILED = "__pmsm_trial_failed__"


def _in_worker(fn: Callable[[dict], dict], firmware: str, task: dict[str, Any]) -> dict:
    """``fn(task)`` in a worker: its result, or why it failed (the firmware build, an exception)."""
    from pmsm_hil.emulator.fwlib import other_build

    why = other_build(firmware)
    if why is not None:
        return {_FAILED: why}
    try:
        return fn(task)
    except Exception as e:
        return {_FAILED: f"{type(e).__name__}: {e}"}


def _normal(value: Any) -> Any:
    return json.loads(json.dumps(value))


def run_tasks(
    fn: Callable[[dict], dict],
    tasks: list[dict[str, Any]],
    out: Path | None = None,
    *,
    name: str = "trial",
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    done_if: Callable[[dict, dict], bool] | None = None,
) -> list[dict[str, Any]]:
    """``fn`` over ``tasks`` on Dask; the results in the order of ``tasks``. A trial whose worker
    died twice gives ``{"error": "..."}``. With ``out``, finished trials go to OUT/NAME.jsonl as
    they end and a later call with the same trials runs only those not done (and, with
    ``done_if(trial, result)``, those for which it holds: e.g. the trial's log is still there)."""
    from distributed import as_completed

    from pmsm_hil.emulator.fwlib import source_id

    firmware = source_id()
    keys = [task_key(t, firmware) for t in tasks]
    results: dict[str, dict[str, Any]] = {}
    journal = None
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        journal = Journal(Path(out), f"{name}.jsonl")
        by_key = dict(zip(keys, tasks, strict=False))
        for k in journal.done():
            if k in by_key and (done_if is None or done_if(by_key[k], journal.rows[k]["result"])):
                results[k] = journal.rows[k]["result"]
    todo = {k: t for k, t in zip(keys, tasks, strict=False) if k not in results}
    bar = _Bar(
        len(set(keys)), len(set(keys)) - len(todo), enabled=progress, label=name, unit="trials"
    )
    if progress and out is not None and results and not todo:
        print(
            f"{name}: all {len(results)} trials taken from {Path(out, name + '.jsonl')} (this "
            "firmware build, the same inputs; remove it to run them again)",
            file=sys.stderr,
        )
    elif progress and out is not None and results:
        print(
            f"{name}: resuming: {len(results)} of {len(set(keys))} trials taken from "
            f"{Path(out, name + '.jsonl')}, {len(todo)} to run",
            file=sys.stderr,
        )
    if todo:
        client = cluster = None
        t0 = time.perf_counter()
        try:
            with _interrupts_held():  # a Ctrl-C while the cluster starts: no worker's traceback
                client, cluster = _client(scheduler, workers)
            futures = [
                client.submit(_in_worker, fn, firmware, t, key=f"pmsm-{name}-{k}", pure=False)
                for k, t in todo.items()
            ]
            prefix = len(f"pmsm-{name}-")
            with bar:
                for fut in as_completed(futures):
                    k = fut.key[prefix:]
                    status = "ok"
                    try:
                        res = _normal(fut.result())
                    except Exception as e:
                        res, status = {"error": _error_of(e)}, "failed"
                    if _FAILED in res:
                        res, status = {"error": res[_FAILED]}, "failed"
                    fut.release()
                    results[k] = res
                    if journal is not None:
                        journal.add({"key": k, "status": status, "result": res})
                    bar.advance(status == "ok", time.perf_counter() - t0)
        except KeyboardInterrupt:
            n = len(set(keys))
            kept = (
                f"kept in {Path(out, name + '.jsonl')}: the same command resumes there"
                if out is not None
                else "not kept (with an output folder, --out DIR, an interrupted run resumes)"
            )
            print(
                f"{name}: interrupted with {sum(k in results for k in set(keys))} of {n} trials "
                f"done; {kept}",
                file=sys.stderr,
            )
            raise
        finally:
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
    return [results[k] for k in keys]
