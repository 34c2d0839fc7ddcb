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

from pmsm_hil.seeds import SEED_MAX

__all__ = [
    "SEEDS_MAX",
    "BenchInputError",
    "Cluster",
    "groups",
    "key_text",
    "logs_written",
    "parse_rigs",
    "parse_seeds",
    "run_trials",
]

SEEDS_MAX = 10_000  # seeds in one benchmark's list: more is a typo, not a plan (each is a run)


class BenchInputError(ValueError):
    """A benchmark's input is refused before anything runs (the CLI: exit 2): seeds that are no
    list of seeds, a scenario that does not exist, a profile that does not identify."""


def parse_seeds(text: str) -> list[int]:
    """ "1-10", "1,2,5" or "1-3,7" -> the seeds, in the order given. Each seed is a whole number in
    0..SEED_MAX; a range A-B has A <= B; at least one seed, none twice, at most SEEDS_MAX;
    BenchInputError saying which part is wrong otherwise."""
    example = "e.g. 1-10, 1,2,5 or 1-3,7"
    out: list[int] = []
    seen: set[int] = set()
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        a, dash, b = part.partition("-")
        lo, hi = _seed(a.strip(), part, example), _seed(b.strip() if dash else a, part, example)
        if hi < lo:
            raise BenchInputError(
                f"the range {part} is empty (give the lower seed first, e.g. {hi}-{lo})"
            )
        if len(out) + hi - lo + 1 > SEEDS_MAX:
            raise BenchInputError(f"more than {SEEDS_MAX} seeds (each seed is a run of every rig)")
        for s in range(lo, hi + 1):
            if s in seen:
                raise BenchInputError(f"seed {s} is given twice")
            seen.add(s)
            out.append(s)
    if not out:
        raise BenchInputError(f"no seeds given ({example})")
    return out


def parse_rigs(text: str) -> list[str]:
    """ "default,lab-typical" -> the rigs (shipped names or files, found by their runs); at least
    one, none twice, BenchInputError otherwise."""
    out: list[str] = []
    for rig in (r.strip() for r in text.split(",")):
        if rig in out:
            raise BenchInputError(f"rig {rig} is given twice")
        if rig:
            out.append(rig)
    if not out:
        raise BenchInputError("no rigs given (e.g. default,lab-typical)")
    return out


def _seed(text: str, part: str, example: str) -> int:
    if text.isascii() and text.isdigit() and int(text) <= SEED_MAX:
        return int(text)
    raise BenchInputError(
        f"{part!r} is not a seed or a range of seeds (whole numbers 0..{SEED_MAX}; {example})"
    )


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
