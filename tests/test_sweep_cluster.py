"""The sweep's cluster and its interruptions: a scheduler address that is not Dask's or does not
answer, Ctrl-C and SIGTERM while the local cluster starts or runs, Dask's default port taken, the
report of a sweep stopped before its first run."""

from __future__ import annotations

import subprocess
import sys

import pytest
from cli_helpers import CLI, cli


def test_a_scheduler_address_dask_does_not_know_is_said(tmp_path):
    r = cli("sweep", "tolerance", "--out", str(tmp_path / "o"), "--scheduler", "http://127.0.0.1:1")
    assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
    assert "cannot reach the scheduler http://127.0.0.1:1" in r.stderr
    assert "tcp://HOST:8786" in r.stderr


def test_a_server_that_takes_the_connection_and_says_nothing_is_not_waited_on_forever(tmp_path):
    """The scheduler's dashboard (tcp://HOST:8787) given for its address: a server that accepts the
    connection and never speaks. Dask's client waited for its handshake without end; the sweep
    says within its 10 s that no scheduler answered there (exit 3)."""
    import socket
    import time

    with socket.create_server(("127.0.0.1", 0)) as silent:  # connections queue, nothing is said
        addr = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        t0 = time.monotonic()
        r = subprocess.run(
            [*CLI, "sweep", "tolerance", "--out", str(tmp_path / "o"), "--scheduler", addr],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
    assert f"cannot reach the scheduler {addr}: " in r.stderr
    assert "did not answer as a Dask scheduler in 11 s" in r.stderr
    assert time.monotonic() - t0 < 40


@pytest.mark.parametrize(
    ("when", "signame"), [("running", "SIGINT"), ("starting", "SIGINT"), ("running", "SIGTERM")]
)
def test_ctrl_c_on_a_local_sweep_leaves_only_its_summary(tmp_path, when, signame):
    """SIGINT to the whole process group, as a terminal's Ctrl-C, once the sweep is running (the
    workers ignore it: sweep/worker_setup.py; the cluster closes them) or while its local cluster
    starts (the workers inherit SIGINT blocked until they ignore it: driver._interrupts_held): the
    sweep says it was interrupted and how to resume, exit 130, no worker's traceback. SIGTERM to
    the sweep's process (a `kill`, a job's time limit) is taken alike (it used to end the process
    with -15, the table unwritten)."""
    import os
    import signal
    import time

    # as from a terminal: a job started in the background of a non-interactive shell (CI)
    # inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    start = (
        "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "sys.argv = ['pmsm-hil', *sys.argv[1:]]; "
        "runpy.run_module('pmsm_hil.cli.main', run_name='__main__')"
    )
    out = str(tmp_path / "out")
    p = subprocess.Popen(
        [sys.executable, "-c", start, "sweep", "tolerance", "--no-progress", "--out", out],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    journal = tmp_path / "out" / "results.jsonl"
    meta = tmp_path / "out" / "sweep.json"  # written just before the cluster starts
    deadline = time.monotonic() + 120.0
    if when == "starting":
        while not meta.is_file() and p.poll() is None:
            assert time.monotonic() < deadline, "the sweep did not start in 120 s"
            time.sleep(0.02)
        time.sleep(0.4)  # the cluster's start takes a second or more on this machine
        assert not journal.is_file() or not journal.read_text().strip(), "too late"
    while when == "running" and not (journal.is_file() and journal.read_text().strip()):
        assert p.poll() is None and time.monotonic() < deadline, "no run finished in 120 s"
        time.sleep(0.2)  # a run has finished: the workers are up
    if signame == "SIGINT":
        os.killpg(p.pid, signal.SIGINT)
    else:
        os.kill(p.pid, getattr(signal, signame))
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, out + err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert "interrupted: run the same command again to resume" in out


def test_a_local_cluster_does_not_warn_when_dasks_default_port_is_taken():
    """A cluster already running on the machine holds 8787 (Dask's default for the scheduler's
    HTTP server); the local sweep's scheduler takes a free port instead of warning about it."""
    import socket
    import warnings

    from pmsm_hil.sweep.driver import _client

    held = socket.socket()
    held.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        held.bind(("127.0.0.1", 8787))
        held.listen()
    except OSError:
        pass  # taken already: the case itself
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            client, cluster = _client(None, 1)
            client.close()
            cluster.close()
        assert not [w for w in seen if "already in use" in str(w.message)]
    finally:
        held.close()


def test_the_scheduler_check_works_from_inside_an_event_loop():
    """run_runs/run_tasks are library calls, and a notebook runs them inside its event loop:
    the handshake check with a deadline must not need the calling thread's loop."""
    import asyncio
    import socket

    from pmsm_hil.sweep.driver import _probe

    async def inside() -> str:
        with socket.create_server(("127.0.0.1", 0)) as silent:
            addr = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
            try:
                _probe(addr, timeout_s=0.5)
            except OSError as e:
                return str(e)
        return ""

    assert "did not answer as a Dask scheduler in 1.5 s" in asyncio.run(inside())


def test_the_report_of_a_sweep_interrupted_before_its_first_run_says_how_to_resume(
    tmp_path, capsys
):
    """A Ctrl-C before any run finished leaves an empty table: `sweep report` says so and that
    the same sweep command resumes it (exit 2, no traceback)."""
    from pmsm_hil.cli.main import main
    from pmsm_hil.sweep.results import write_table

    out = tmp_path / "tol"
    out.mkdir()
    write_table(out, [], [])
    assert main(["sweep", "report", str(out)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "the table is empty: no run finished" in err
    assert f"`pmsm-hil sweep SWEEP --out {out}` again resumes it" in err
