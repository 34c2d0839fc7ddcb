"""One run of a sweep, in the calling process: the emulator in process (no pty, no child), the log
written directly, the metrics computed from it. This is what a Dask worker executes.

A run that cannot be made (invalid inputs, a host or device error) is returned with status
"failed" and its error, never raised: one bad run does not end the sweep. A run stopped before its
end (a Ctrl-C, or the sweep's interrupt: sweep/wind_down.py) is returned with status "interrupted"
and no metrics; its kept log holds what it ran.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable

    from pmsm_hil.profiles import Profile
    from pmsm_hil.runner import RunResult

__all__ = ["execute_run", "run_in_process"]


def run_in_process(
    profile: Profile,
    log_path: str | os.PathLike,
    seed: int,
    stop_requested: Callable[[], str] | None = None,
) -> RunResult:
    """Run ``profile`` on the in-process emulator with ``seed``, logging to ``log_path``: the same
    device data as `pmsm-hil run PROFILE --seed SEED` on the emulator. ``stop_requested``:
    RunOptions.stop_requested (the sweep's interrupt, sweep/wind_down.py)."""
    from pmsm_hil.device import DeviceSpec, emulator_settings_for
    from pmsm_hil.protocol.session import Session
    from pmsm_hil.runner import RunOptions, run_profile
    from pmsm_hil.transport.inproc import InProcessTransport

    settings = emulator_settings_for(profile, DeviceSpec(seed=seed))
    return run_profile(
        profile,
        Session(InProcessTransport(settings)),
        Path(log_path),
        RunOptions(seed=seed, rig_name=profile.rig.name, stop_requested=stop_requested),
    )


def execute_run(task: dict[str, Any]) -> dict[str, Any]:
    """Run one task of ``Run.task()``; return its result row (metrics, status, error, log path)."""
    from pmsm_hil.profiles import ProfileError, load_profile

    from .metrics import run_metrics
    from .wind_down import NOT_STARTED, stop_request

    t_wall = time.perf_counter()
    row: dict[str, Any] = {"key": task["key"], "status": "failed", "error": "", "log_path": ""}
    from pmsm_hil.emulator.fwlib import other_build

    why = other_build(task.get("firmware", ""))
    if why is not None:
        row.update(error=why, wall_s=0.0)
        return row
    stop = stop_request(task.get("stop_event"))
    if stop is not None and stop():  # the sweep was interrupted before this run began
        row.update(status="interrupted", error=NOT_STARTED, wall_s=0.0)
        return row
    tmp = tempfile.mkdtemp(prefix=f"pmsm-sweep-{task['key']}-")
    # a kept log is written where it is kept, from the start: an interrupted or failed run, or a
    # worker that dies, leaves it there (an unfinalised log with its journal: `pmsm-hil log
    # recover`)
    log = Path(task["log_path"]) if task.get("log_path") else Path(tmp, "run.mcap")
    try:
        for name, text in task["texts"].items():
            Path(tmp, name).write_text(text, encoding="utf-8")
        try:
            profile = load_profile(os.path.join(tmp, "profile.yaml"))
            if task.get("commission"):
                from .commissioned import commission_then_load

                commissioned, why = commission_then_load(Path(tmp), task["seed"])
                if commissioned is None:
                    row["error"] = why
                    return row
                profile = commissioned
        except ProfileError as e:
            row["error"] = "invalid inputs: " + str(e).replace(tmp + os.sep, "").replace("\n", "; ")
            return row
        if task.get("log_path"):
            log.parent.mkdir(parents=True, exist_ok=True)
        result = run_in_process(profile, log, task["seed"], stop)
        row["state"] = result.state
        row["stop_reason"] = result.stop_reason
        if result.interrupted:  # Ctrl-C, SIGTERM, SIGHUP or the sweep's interrupt stopped it:
            # not a result to judge (no metrics), but its log is kept as far as it went
            row.update(
                status="interrupted",
                interrupted=True,
                error="interrupted: " + (result.error or "stopped before the profile's end"),
            )
            return row
        if result.error:
            row["error"] = f"run error: {result.error}"
        row.update(run_metrics(log, profile, task["metrics"]))
        row["status"] = "ok" if not result.error else "failed"
        return row
    except Exception as e:
        row["error"] = f"{type(e).__name__}: {e}"
        return row
    finally:
        if task.get("log_path") and log.exists():
            row["log_path"] = str(log)
        row["wall_s"] = time.perf_counter() - t_wall
        shutil.rmtree(tmp, ignore_errors=True)
