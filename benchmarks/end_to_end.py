"""End to end: `pmsm-hil run`, the emulator loop, and `analyze` of a one-hour log, as ratios.

    nice python3 benchmarks/end_to_end.py [--repeat 5] [--log hour.mcap] [--skip run,loop,analyze]

- **run**: `pmsm-hil run profiles/paper-a.yaml --seed 1 --no-live` in a fresh process (the CLI, the
  emulator child on its pty, the recorder and MCAP writer, the summary): device time / wall time,
  and the CPU time of the host and its emulator child together (user + sys).
- **loop**: the emulator alone in this process (firmware core + sim board + plant, the UART's
  octets produced and dropped; benchmarks/emulator_speed.py) on the default rig and on
  lab-typical: device time / wall time and ns per 50 us control period; with gym-electric-motor
  installed (`pip install -e '.[bench]'`) its finite-control-set environment beside it.
- **analyze**: `pmsm-hil analyze` of a one-hour log at the contract's fastest rates (telemetry
  2 kHz, params 4 x 100 Hz, status 10 Hz, truth 100 Hz; written once by benchmarks/log_reader.py's
  generator and kept at --log): wall time, CPU time and peak RSS of that process.

`--base DIR`: the same `run` and `analyze` commands with another source tree of pmsm-hil (e.g.
`git archive COMMIT | tar -x -C DIR` and the compiled extension `pmsm_hil/_fw*.so` copied in; on
PYTHONPATH, so its emulator child is that tree's too), interleaved with this one's, and the speed-up
as the median of the per-pair ratios: a comparison that holds on a loaded machine.

The machine this runs on is often shared: each figure is the median over --repeat runs (the worst
beside it), wall-clock ratios move with the load, the CPU times less so; the load average at the
start is printed.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
CLI = [sys.executable, "-m", "pmsm_hil.cli.main"]
PAPER_A_S = 32.55  # device time of profiles/paper-a.yaml


def timed(cmd: list[str], **kw) -> dict:
    """Wall time, CPU time (user + sys, of the process and of the children it waited for) and peak
    RSS of a command."""
    t0 = time.perf_counter()
    kw.setdefault("cwd", tempfile.gettempdir())  # not a source tree: `-m` would import from it
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **kw)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    err = p.stderr.read().decode(errors="replace")
    p.stderr.close()
    return {
        "wall_s": wall,
        "cpu_s": ru.ru_utime + ru.ru_stime,
        "rss_mib": ru.ru_maxrss / 1024,
        "code": p.returncode,
        "stderr": err,
    }


def med(values) -> float:
    return statistics.median(values)


def _envs(base: str | None) -> dict[str, dict]:
    """The environment of the timed commands, per tree: as an installed pmsm-hil runs, with its
    modules' byte code cached (pip compiles it at install; an editable tree writes __pycache__ at
    its first import). PYTHONDONTWRITEBYTECODE, when the calling shell sets it, is dropped: with it
    every command would compile the package's ~100 modules from source, in the host and again in
    the emulator child."""
    user = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    envs = {"this tree": user}
    if base:
        envs["base"] = {**user, "PYTHONPATH": os.path.abspath(base)}
    return envs


def warm(envs: dict[str, dict]) -> None:
    """One untimed import per tree of what the timed commands import (the host's CLI, runner,
    analysis and report, the emulator child's entry), so that the byte-code caches exist before
    the first timed command."""
    # each module that the tree has (an older base tree, e.g. wave 1's, lacks some)
    code = (
        "import importlib.util as u\n"
        "for m in ('pmsm_hil.cli.main', 'pmsm_hil.cli.run', 'pmsm_hil.cli.analyze', "
        "'pmsm_hil.cli.report', 'pmsm_hil.cli.log', 'pmsm_hil.runner', "
        "'pmsm_hil.analysis.summary', 'pmsm_hil.emulator.entry'):\n"
        "    if u.find_spec(m) is not None: __import__(m)"
    )
    for env in envs.values():
        subprocess.run([sys.executable, "-c", code], env=env, check=True, cwd=tempfile.gettempdir())


def interleaved(name: str, repeat: int, base: str | None, command, ok=None, after=None) -> dict:
    """``repeat`` rounds of ``pmsm-hil *command(i)``, one per tree in each round (this tree and the
    base, interleaved), each in a fresh process: {tree: [timed(...)]}. ``ok(result)`` judges a
    run (default: exit 0, no traceback; otherwise the benchmark stops with its stderr); ``after(i)``
    runs after each command (e.g. removes its output)."""
    ok = ok or (lambda r: r["code"] == 0 and "Traceback" not in r["stderr"])
    envs = _envs(base)
    warm(envs)
    runs: dict[str, list[dict]] = {k: [] for k in envs}
    for i in range(repeat):
        for label, env in envs.items():
            r = timed([*CLI, *command(i)], env=env)
            if not ok(r):
                sys.exit(f"{name} ({label}) failed: {r['stderr'][-2000:]}")
            runs[label].append(r)
            if after is not None:
                after(i)
    return runs


def _pairs(name: str, runs: dict[str, list[dict]], key: str) -> None:
    """The speed-up of this tree over the base, per interleaved pair."""
    if "base" in runs:
        ratios = [b[key] / a[key] for a, b in zip(runs["this tree"], runs["base"], strict=True)]
        print(
            f"  {name}: this tree / base, {key}: median {med(ratios):.2f}x faster "
            f"(range {min(ratios):.2f}-{max(ratios):.2f}x over {len(ratios)} pairs)"
        )


def bench_run(repeat: int, base: str | None = None) -> None:
    paper_a = str(ROOT / "profiles" / "paper-a.yaml")
    with tempfile.TemporaryDirectory() as d:
        runs = interleaved(  # CPU: the emulator child's included
            "run",
            repeat,
            base,
            # --overwrite: the base tree's run writes the same file after this tree's
            lambda i: [
                *("run", paper_a, "--seed", "1", "--no-live", "--overwrite"),
                *("--out", f"{d}/a{i}.mcap"),
            ],
        )
    for label, rs in runs.items():
        walls = [r["wall_s"] for r in rs]
        cpus = [r["cpu_s"] for r in rs]
        print(
            f"run paper-a ({PAPER_A_S} s of device time), {label}, {repeat} runs: median "
            f"{med(walls):.2f} s wall = {PAPER_A_S / med(walls):.1f}x real time (worst "
            f"{PAPER_A_S / max(walls):.1f}x); CPU host + emulator median {med(cpus):.2f} s = "
            f"{PAPER_A_S / med(cpus):.1f}x"
        )
    _pairs("run", runs, "wall_s")
    _pairs("run", runs, "cpu_s")


def bench_loop(repeat: int) -> None:
    from emulator_speed import emulator_realtime_factor

    rigs = {"default": None, "lab-typical": str(ROOT / "profiles" / "rigs" / "lab-typical.yaml")}
    try:
        import gym_electric_motor  # noqa: F401
        from gem_fcs import gem_realtime_factor
    except ImportError as e:
        gem_realtime_factor = None
        print(f"gym-electric-motor not measured: {e}")
    ours: dict = {k: [] for k in rigs}
    gems = []
    for _ in range(repeat):
        for name, rig in rigs.items():
            ours[name].append(
                emulator_realtime_factor(str(ROOT / "profiles" / "paper-a.yaml"), rig)
            )
        if gem_realtime_factor is not None:
            gems.append(gem_realtime_factor(sim_seconds=0.5, tau=50e-6, repeats=1))
    gem_med = med([g["realtime_factor"] for g in gems]) if gems else None
    for name, runs in ours.items():
        f = [r["realtime_factor"] for r in runs]
        fc = [r["cpu_realtime_factor"] for r in runs]
        ns = med([r["ns_per_period"] for r in runs])
        line = (
            f"emulator loop, rig {name}, {repeat} runs: median {med(f):.0f}x real time "
            f"(worst {min(f):.0f}x), {ns:.0f} ns per 50 us period; per CPU second "
            f"{med(fc):.0f}x (worst {min(fc):.0f}x)"
        )
        if gem_med:
            line += f"; gym-electric-motor {gem_med:.2f}x, ratio {med(f) / gem_med:.0f}x"
        print(line)


def hour_log(log: str | None) -> str:
    """The one-hour log at the contract's fastest rates: ``log`` (or one in the temporary
    directory), written by benchmarks/log_reader.py's generator if it is not there yet."""
    from log_reader import make_log

    path = log or os.path.join(tempfile.gettempdir(), "pmsm-hil-hour.mcap")
    if not os.path.exists(path):
        t0 = time.perf_counter()
        make_log(path, 60.0)
        print(
            f"wrote {path} ({os.path.getsize(path) / 2**20:.0f} MiB) in {time.perf_counter() - t0:.0f} s"
        )
    return path


def bench_analyze(repeat: int, log: str | None, base: str | None = None) -> None:
    path = hour_log(log)
    # exit 1 is "bounds missed" (a synthetic log); anything on stderr is a failure
    runs = interleaved(
        "analyze",
        repeat,
        base,
        lambda i: ["analyze", path],
        ok=lambda r: r["code"] in (0, 1) and not r["stderr"].strip(),
    )
    size = os.path.getsize(path) / 2**20
    for label, rs in runs.items():
        w = [r["wall_s"] for r in rs]
        c = [r["cpu_s"] for r in rs]
        m = [r["rss_mib"] for r in rs]
        print(
            f"analyze one hour at 2 kHz ({size:.0f} MiB), {label}, {repeat} runs: median "
            f"{med(w):.1f} s wall (worst {max(w):.1f} s), CPU {med(c):.1f} s (worst {max(c):.1f} s), "
            f"peak RSS {med(m):.0f} MiB (worst {max(m):.0f} MiB)"
        )
    _pairs("analyze", runs, "wall_s")
    _pairs("analyze", runs, "cpu_s")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--log", default=None, help="the one-hour log (written there if missing)")
    ap.add_argument("--skip", default="", help="comma-separated: run, loop, analyze")
    ap.add_argument(
        "--base", default=None, help="another source tree to compare with (run, analyze)"
    )
    args = ap.parse_args()
    skip = set(filter(None, args.skip.split(",")))
    print(f"load average at the start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    if "run" not in skip:
        bench_run(args.repeat, args.base)
    if "loop" not in skip:
        bench_loop(args.repeat)
    if "analyze" not in skip:
        bench_analyze(args.repeat, args.log, args.base)


if __name__ == "__main__":
    main()
