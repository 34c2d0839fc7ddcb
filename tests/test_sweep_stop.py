"""The runs in progress when a sweep or a multi-profile `pmsm-hil test` is interrupted: each stops
its motor under control and keeps its log as far as it went (sweep/wind_down.py), as a single
`pmsm-hil run` does; the runs not started are not run. Before, the cluster's close killed the
workers mid-run and the partial logs were lost with their temporary folders."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from pmsm_hil.sweep.results import Journal

# as from a terminal (a job in the background of a non-interactive shell, CI, starts with SIGINT
# ignored); SIGTERM is taken as Ctrl-C by every command
START = [
    sys.executable,
    "-c",
    "import runpy, sys; sys.argv = ['pmsm-hil', *sys.argv[1:]]; "
    "runpy.run_module('pmsm_hil.cli.main', run_name='__main__')",
]


def _interrupt_once_logging(args: list[str], logs: Path) -> tuple[int, str, str]:
    """Run the CLI, SIGTERM it once a run's log in ``logs`` has grown past 50 kB."""
    p = subprocess.Popen([*START, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not any(f.stat().st_size > 50_000 for f in logs.glob("*.mcap")):
        assert p.poll() is None and time.monotonic() < deadline, "no run started logging"
        time.sleep(0.05)
    os.kill(p.pid, signal.SIGTERM)
    out, err = p.communicate(timeout=120)
    return p.returncode, out, err


def _stopped_log(path: Path) -> list[str]:
    """The log's events, after checking it is finalised and that the generic reader opens it."""
    from mcap.reader import make_reader

    from pmsm_hil.log.reader import read_log

    assert path.is_file() and not Path(str(path) + ".journal").exists()
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics.message_count > 1000
    log = read_log(path)
    assert log.finalised
    return list(log.topic("/pmsm/events")["text"])


def test_an_interrupted_suite_keeps_the_log_of_the_run_it_stopped(tmp_path, data):
    out = tmp_path / "out"
    code, stdout, err = _interrupt_once_logging(
        ["test", str(data / "long.yaml"), str(data / "short.yaml"), "--out", str(out)], out / "logs"
    )
    assert code == 130, stdout + err
    assert "Traceback" not in err, err
    assert "interrupted: stopping the runs in progress, their logs kept" in err
    line = next(s for s in stdout.splitlines() if s.startswith("NOT JUDGED long"))
    assert "interrupted; its log so far " in line, stdout
    log = Path(line.split("its log so far ", 1)[1].strip())
    events = _stopped_log(log)
    assert "interrupted by the sweep's interrupt: stop sent" in events
    assert events[-1].startswith("stopped: host stop"), events[-3:]


def test_an_interrupted_sweep_lists_its_stopped_runs_and_resumes_them(tmp_path, data):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(
        f"name: t\nprofile: {data / 'long.yaml'}\nmetrics: [faults]\nkeep_logs: true\n"
        "axes:\n  - {field: seed, values: [1, 2, 3]}\n"
    )
    out = tmp_path / "out"
    code, stdout, err = _interrupt_once_logging(
        ["sweep", str(sweep), "--out", str(out), "--workers", "1", "--no-progress"], out / "logs"
    )
    assert code == 130, stdout + err
    assert "1 stopped by the interrupt" in stdout and "Traceback" not in err, stdout + err
    with open(out / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == ["interrupted"], rows  # runs 1 and 2 never began
    assert f"run 0 ({rows[0]['key']}) stopped: its log {rows[0]['log_path']} holds" in stdout
    assert "interrupted by the sweep's interrupt: stop sent" in _stopped_log(
        Path(rows[0]["log_path"])
    )
    assert rows[0]["key"] not in Journal(out).done()  # the same command runs it again
    # the report counts it as stopped, not as a run that failed to run
    r = subprocess.run([*START, "sweep", "report", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    summary = (out / "report" / "summary.md").read_text()
    assert "1 runs: 0 completed, 0 failed to run, 1 stopped by an interrupt" in summary, summary
    assert f"- run 0: its log so far {rows[0]['log_path']}" in summary
