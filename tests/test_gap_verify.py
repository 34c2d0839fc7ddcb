"""`pmsm-hil gap verify` (the log's profile re-run on a fitted rig, compared at the control rate)
and a Ctrl-C during a diagnosis."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from pmsm_hil.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
PROFILE = ROOT / "tests/data/gap-short.yaml"


def test_verify_reruns_the_logs_profile(tmp_path, capsys):
    from pmsm_hil.gapgen.recorder import record_profile
    from pmsm_hil.gapgen.verify import verify

    rig = ROOT / "profiles/rigs/effect-dead-time.yaml"
    real = tmp_path / "real.mcap"
    record_profile(PROFILE, real, rig_path=rig, seed=4)
    same = verify(real, rig, seed=4)  # the true rig and seed reproduce the log exactly
    assert same["stopped_early"] == {}  # both re-runs played the profile to its end
    assert all(s["rms_fitted"] == 0.0 and s["closure"] == 1.0 for s in same["signals"].values())
    assert all(s["rms_fitted"] == 0.0 and s["closure"] == 1.0 for s in same["plateau"].values())
    nominal = verify(real, ROOT / "profiles/rigs/ideal.yaml", seed=4)
    assert all(s["closure"] == 0.0 for s in nominal["signals"].values())
    assert all(s["closure"] == 0.0 for s in nominal["plateau"].values())
    # the dead time shows in the settled voltages: the ideal plant misses them, the true rig not
    assert nominal["plateau"]["u_q_v"]["rms_nominal"] > 0.2
    assert nominal["signals"]["u_q_v"]["rms_nominal"] > 0.5
    assert main(["gap", "verify", str(real), "--rig", str(rig), "--seed", "4"]) == 0
    # the closure printed is 1 - MSE_fitted / MSE_nominal, and the note says so
    assert "closure = 1 - (fitted / nominal rms error)^2" in capsys.readouterr().out
    # a shipped rig by its name, as `gap record --rig` takes it: the true rig, closure 1
    assert main(["gap", "verify", str(real), "--rig", "effect-dead-time", "--seed", "4"]) == 0
    assert "free-run closure (median over i_d, i_q, u_d, u_q) 1.00" in capsys.readouterr().out
    assert main(["gap", "verify", str(real), "--rig", "no-such-rig"]) == 2
    assert "no-such-rig: is neither a file nor a shipped rig" in capsys.readouterr().err


def test_a_rerun_that_stopped_early_is_said(tmp_path, capsys, monkeypatch):
    """A fitted rig whose re-run faulted (the SEW rig's fitted map, before its inductances were
    held beyond the record's currents: over_current at 1.505 s) was scored over the whole profile
    and read as a closure of -91 with nothing said; the stop is found in the re-run's events and
    printed first."""
    from pmsm_hil.gapgen import verify as v

    class Events:
        def __init__(self, rows):
            self.rows, self.topics = rows, ["/pmsm/events"]

        def topic(self, name):
            return {k: [r[i] for r in self.rows] for i, k in enumerate(("t_s", "kind", "text"))}

    fault = Events([(0.0, "started", "started"), (1.505, "stopped", "stopped: fault")])
    assert v._early_stop(fault) == {"t_s": 1.505, "why": "stopped: fault"}
    done = Events([(0.0, "started", "started"), (9.0, "stopped", "stopped: profile end")])
    assert v._early_stop(done) is None
    scores = {"rms_nominal": 1.0, "rms_fitted": 2.0, "closure": -3.0}
    result = {
        "signals": {"i_d_a": scores},
        "plateau": {"i_d_a": scores},
        "closure_median": -3.0,
        "plateau_closure_median": -3.0,
        "stopped_early": {"fitted": {"t_s": 1.505, "why": "stopped: fault"}},
    }
    monkeypatch.setattr(v, "verify", lambda *a, **k: result)
    log = tmp_path / "x.mcap"
    log.write_bytes(b"a log to the path check; verify itself is stood in for")
    assert main(["gap", "verify", str(log), "--rig", "ideal"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(
        "gap verify: the fitted rig's re-run stopped at 1.505 s (stopped: fault): its signals "
        "are compared up to there"
    ), out


def test_verify_compares_the_control_rate_not_the_telemetrys_samples(tmp_path):
    """The true rig run again with another noise seed reproduces every segment's settled dq
    currents and voltages (closure >= 0.9): they come from the control-rate recording, every period.
    The 2 kHz telemetry of earlier firmware builds sampled one period in ten of the FCS voltage,
    whose aliases moved a settled u_d by volts between two seeds (closure -0.3 to 0 on diagnose.yaml,
    lab-typical). A log without the recording is compared on its telemetry."""
    from pmsm_hil.gapgen.recorder import record_profile
    from pmsm_hil.gapgen.verify import SIGNALS, _series, verify
    from pmsm_hil.log.reader import read_log

    rig = ROOT / "profiles/rigs/lab-typical.yaml"
    real = tmp_path / "real.mcap"
    record_profile(ROOT / "profiles/diagnose.yaml", real, rig_path=rig, seed=3)
    other = verify(real, rig, seed=1)
    for s in ("i_d_a", "i_q_a", "u_d_v", "u_q_v"):
        assert other["plateau"][s]["closure"] >= 0.9, (s, other["plateau"][s])
        assert other["signals"][s]["closure"] >= 0.7, (s, other["signals"][s])

    class TelemetryOnly:  # the same log without its control-rate topic
        def __init__(self, log):
            self.log, self.topics = log, [t for t in log.topics if t != "/pmsm/control_rate"]

        def topic(self, name):
            return self.log.topic(name)

    log = read_log(real)
    ser, tel = _series(log, real), _series(TelemetryOnly(log), real)
    n_tel = len(log.topic("/pmsm/telemetry")["t_s"])
    assert all(len(tel[s][0]) == n_tel for s in SIGNALS)
    assert len(ser["u_d_v"][0]) > 5 * n_tel and len(ser["speed_rpm"][0]) == n_tel


def test_ctrl_c_stops_the_diagnosis_and_its_fit_processes(tmp_path):
    """Ctrl-C during a long diagnosis (a lab-typical record, about a minute): one line and 130,
    no traceback, and the fit processes end with it."""
    import signal
    import time

    log = tmp_path / "real.mcap"
    cli = [sys.executable, "-m", "pmsm_hil.cli.main", "gap"]
    rig = str(ROOT / "profiles/rigs/lab-typical.yaml")
    rec = [*cli, "record", str(ROOT / "profiles/diagnose.yaml"), "--rig", rig, "-o", str(log)]
    subprocess.run(rec, check=True, capture_output=True, cwd=tmp_path)
    # Ctrl-C's KeyboardInterrupt installed explicitly (a shell's background job passes SIGINT
    # ignored, and Python then keeps it so)
    interruptible = (
        "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "sys.argv = sys.argv[1:]; runpy.run_module('pmsm_hil.cli.main', run_name='__main__')"
    )
    p = subprocess.Popen(
        [sys.executable, "-c", interruptible, "pmsm-hil", "gap", str(log), "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        start_new_session=True,
    )

    def children() -> list[int]:
        out = subprocess.run(["pgrep", "-P", str(p.pid)], capture_output=True, text=True).stdout
        return [int(x) for x in out.split()]

    deadline = time.monotonic() + 60
    while len(children()) < 2 and time.monotonic() < deadline and p.poll() is None:
        time.sleep(0.1)
    kids = children()
    assert len(kids) >= 2, "the diagnosis should have started its fit processes"
    time.sleep(3.0)  # into the forward selection
    assert p.poll() is None
    os.killpg(p.pid, signal.SIGINT)  # the group: what the terminal does
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "pmsm-hil gap: interrupted" in err and "Traceback" not in err
    deadline = time.monotonic() + 30
    while any(os.path.exists(f"/proc/{c}") for c in kids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(os.path.exists(f"/proc/{c}") for c in kids)
