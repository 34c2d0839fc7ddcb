"""Where a benchmark's runs go: one in this process, several as trials on the sweep's Dask
machinery (pmsm_hil.sweep.tasks: a local cluster of one worker process per core or a scheduler by
address, a progress bar, a journal in the output folder that an interrupted benchmark resumes
from). Every benchmark that runs the emulator over rigs, seeds or cases goes through `run_trials`
(docs/sweep.md, "Other trials on the machinery")."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["Cluster", "groups", "key_text", "logs_written", "run_trials"]


@dataclass
class Cluster:
    """Where the benchmark's runs go: workers of a local cluster, or a scheduler's address."""

    workers: int | None = None
    scheduler: str | None = None
    progress: bool = False


def key_text(path: str | Path | None) -> str:
    """A file's text for a trial's key (a changed file runs again); "" for none."""
    return Path(path).read_text(encoding="utf-8") if path else ""


def groups(items: list, size: int) -> list[list]:
    """``items`` cut into consecutive groups of ``size`` (a rig's seeds in rig-major results)."""
    return [items[k : k + size] for k in range(0, len(items), size)]


def logs_written(task: dict[str, Any], result: dict[str, Any]) -> bool:
    """A journalled trial counts as done while the logs it names (task["log"], task["logs"]) are
    all there."""
    paths = [*task.get("logs", ()), *([task["log"]] if "log" in task else [])]
    return all(Path(p).is_file() for p in paths)


def run_trials(
    fn: Callable[[dict[str, Any]], dict[str, Any]],
    tasks: list[dict[str, Any]],
    out: Path,
    cluster: Cluster | None = None,
    *,
    name: str = "bench",
    done_if: Callable[[dict[str, Any], dict[str, Any]], bool] | None = logs_written,
) -> list[dict[str, Any]]:
    """``fn`` (a module-level function: it runs in a worker process) over ``tasks``, the results in
    order. One task without a scheduler runs here; several go to Dask, journalled in
    OUT/NAME.jsonl. A task whose worker failed gives ``{"error": "..."}``."""
    cluster = cluster or Cluster()
    if len(tasks) == 1 and cluster.scheduler is None:
        return [fn(tasks[0])]
    from pmsm_hil.sweep.tasks import run_tasks

    return run_tasks(
        fn,
        tasks,
        out,
        name=name,
        scheduler=cluster.scheduler,
        workers=cluster.workers,
        progress=cluster.progress,
        done_if=done_if,
    )
