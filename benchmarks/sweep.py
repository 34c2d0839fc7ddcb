"""Sweep throughput: N runs of the identification profile (paper-a-identify, seeds 1..N, default
rig) with 1 and 2 local workers (runs per minute, the scaling ratio), then on a two-worker Dask
cluster started as separate processes on loopback (`dask scheduler` + two `dask worker`), whose
results must equal the local run's bit for bit (every column but the wall time and the log path).

    python3 benchmarks/sweep.py [--runs 200] [--workers 1 2] [--no-cluster]

The rates include the cluster's start (a few seconds); the rate of the runs alone is printed
beside them. On a machine shared with other work the scaling ratio measures the machine, not the
sweep: the load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pmsm_hil.sweep import load_sweep, plan_runs, read_table, run_sweep
from pmsm_hil.sweep.driver import SCHEDULER_CONFIG

SKIP = {"wall_s", "log_path"}


def _sweep_file(d: Path, n: int) -> Path:
    p = d / "ident.yaml"
    p.write_text(
        "name: bench-ident\nprofile: paper-a-identify\nmetrics: [identification, speed_error, "
        "ripple, faults, completeness]\naxes:\n"
        f"  - {{field: seed, values: [{', '.join(str(i) for i in range(1, n + 1))}]}}\n"
    )
    return p


def _same(a: list[dict], b: list[dict]) -> tuple[bool, str]:
    if len(a) != len(b):
        return False, f"{len(a)} rows against {len(b)}"
    for ra, rb in zip(a, b, strict=False):
        keys = (set(ra) | set(rb)) - SKIP
        for k in sorted(keys):
            x, y = ra.get(k), rb.get(k)
            both_nan = (
                isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)
            )
            if x != y and not both_nan:
                return False, f"run {ra.get('index')}: {k} = {x!r} against {y!r}"
    return True, f"{len(a)} rows equal"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _cluster(port: int, n_workers: int) -> list[subprocess.Popen]:
    env = dict(os.environ)
    for (
        key,
        value,
    ) in SCHEDULER_CONFIG.items():  # DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES=1 ...
        env["DASK_" + key.upper().replace(".", "__").replace("-", "_")] = str(value)
    dask = [sys.executable, "-m", "dask"]
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
    procs = [
        subprocess.Popen(
            [*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            **quiet,
        )
    ]
    for _ in range(n_workers):
        procs.append(
            subprocess.Popen(
                [
                    *dask,
                    "worker",
                    f"tcp://127.0.0.1:{port}",
                    "--nthreads",
                    "1",
                    "--nworkers",
                    "1",
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                ],
                **quiet,
            )
        )
    return procs


def _wait_workers(addr: str, n: int, timeout_s: float = 60.0) -> None:
    from distributed import Client

    t0 = time.monotonic()
    while True:
        try:
            with Client(addr, timeout="5s") as c:
                c.wait_for_workers(n, timeout=timeout_s)
                return
        except OSError:
            if time.monotonic() - t0 > timeout_s:
                raise
            time.sleep(0.5)


def _line(label: str, res, rows) -> str:
    busy = sum(r.get("wall_s", 0.0) for r in rows)
    return (
        f"{label:<28} {res.ok:4d} ok {res.failed:3d} failed  {res.wall_s:7.1f} s  "
        f"{res.runs_per_min:7.1f} runs/min (with start-up)  "
        f"{60.0 * len(rows) / busy if busy else 0:6.1f} runs/min per worker busy"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--no-cluster", action="store_true", help="skip the loopback cluster")
    ap.add_argument("--keep", default=None, help="keep the output folders here")
    args = ap.parse_args()
    tmp = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="pmsm-bench-sweep-"))
    tmp.mkdir(parents=True, exist_ok=True)
    sweep = load_sweep(_sweep_file(tmp, args.runs))
    runs = plan_runs(sweep)
    print(
        f"sweep benchmark: {len(runs)} runs of paper-a-identify (default rig, seeds 1..{args.runs}); "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at the start"
    )
    rates, local = {}, None
    try:
        for w in args.workers:
            out = tmp / f"local-{w}"
            shutil.rmtree(out, ignore_errors=True)
            res = run_sweep(sweep, out, workers=w, progress=False, runs=runs)
            rows = read_table(out)
            rates[w] = res.runs_per_min
            print(_line(f"local cluster, {w} worker(s)", res, rows), flush=True)
            if w == max(args.workers):
                local = rows
        if 1 in rates and 2 in rates and rates[1] > 0:
            print(
                f"scaling 2 workers / 1 worker: {rates[2] / rates[1]:.2f}x "
                f"(load average now {os.getloadavg()[0]:.2f})"
            )
        if not args.no_cluster:
            port = _free_port()
            procs = _cluster(port, 2)
            try:
                addr = f"tcp://127.0.0.1:{port}"
                _wait_workers(addr, 2)
                out = tmp / "cluster"
                shutil.rmtree(out, ignore_errors=True)
                res = run_sweep(sweep, out, scheduler=addr, progress=False, runs=runs)
                rows = read_table(out)
                print(_line("loopback cluster, 2 workers", res, rows))
                if local is not None:
                    same, why = _same(local, rows)
                    print(
                        f"cluster results equal the local run's bit for bit: {'yes' if same else 'NO'} ({why})"
                    )
                    if not same:
                        return 1
            finally:
                for p in reversed(procs):
                    p.terminate()
                for p in procs:
                    try:
                        p.wait(timeout=10)
                    except subprocess.TimeoutExpired:
                        p.kill()
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
