"""Faults and lost links stop the motor safely and still leave a readable log."""

from __future__ import annotations

import subprocess
import sys
import threading

from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol.session import Session
from pmsm_hil.recorder import FAULT_BITS
from pmsm_hil.runner import RunOptions, run_profile
from pmsm_hil.transport.emulator import EmulatorTransport
from pmsm_hil.transport.inproc import InProcessTransport


def run_with_plant(profile_path, out, **plant):
    profile = load_profile(str(profile_path))
    settings = emulator_settings(profile.motor, profile.rig, seed=1, baud=profile.link.baud)
    settings.update(plant)
    return profile, run_profile(profile, Session(InProcessTransport(settings)), out, RunOptions())


def test_dc_link_under_voltage_trips_at_once(data, tmp_path):
    out = tmp_path / "uv.mcap"
    _, result = run_with_plant(data / "short.yaml", out, v_dc_v=300.0)
    assert result.state == "fault"
    assert result.faults & FAULT_BITS["dc_under_voltage"]
    assert result.stop_reason == "fault"
    ev = read_log(out).topic("/pmsm/events")
    assert "fault" in list(ev["kind"])
    assert any("dc_under_voltage" in t for t in ev["text"])


def test_over_current_switches_the_pwm_off_and_freezes_the_capture(data, tmp_path):
    """The plant's inductances are ten times lower than the firmware believes: each vector
    moves the current by several amperes, and the over-current trip must act."""
    out = tmp_path / "oc.mcap"
    _, result = run_with_plant(data / "short.yaml", out, l_d_h=0.0005, l_q_h=0.0012)
    assert result.state == "fault"
    assert result.faults & FAULT_BITS["over_current"]
    log = read_log(out)
    kinds = list(log.topic("/pmsm/events")["kind"])
    assert "capture_triggered" in kinds
    cap = log.topic("/pmsm/capture")
    assert len(cap["t_s"]) > 0
    # the frozen capture ends at the trip, where a phase current exceeds the trip level
    last = max(abs(cap["i_a_a"][-1]), abs(cap["i_b_a"][-1]), abs(cap["i_c_a"][-1]))
    assert last > 25.0
    # nothing was streamed as running after the trip
    st = log.topic("/pmsm/status")
    assert list(st["state"])[-1] == "fault"


def test_cli_reports_a_device_fault(tmp_path, root):
    """A motor file whose over-current trip sits just above the current limit: a heavy load
    drives the current to the limit, the switching ripple crosses the trip level."""
    motor = tmp_path / "tight-trip.yaml"
    motor.write_text(
        (root / "profiles" / "motors" / "paper-a-ipmsm.yaml")
        .read_text()
        .replace("i_trip_a: 25.0", "i_trip_a: 15.1")
    )
    prof = tmp_path / "heavy.yaml"
    prof.write_text(
        f"name: heavy\nmotor: {motor}\nrig: {root}/profiles/rigs/default.yaml\n"
        "segments:\n  - {duration_s: 0.5, speed_rpm: 200, ramp_rpm_s: 1000}\n"
        "  - {duration_s: 1.0, speed_rpm: 200, load_nm: 17.0}\n"
    )
    out = tmp_path / "f.mcap"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pmsm_hil.cli.main",
            "run",
            str(prof),
            "--out",
            str(out),
            "--no-live",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 4, r.stderr
    assert "over_current" in r.stderr
    assert "Traceback" not in r.stderr
    assert list(read_log(out).topic("/pmsm/status")["state"])[-1] == "fault"


def test_dropped_link_ends_the_run_with_a_readable_log(data, tmp_path):
    profile = load_profile(str(data / "long.yaml"))
    tr = EmulatorTransport(str(profile.motor.path), str(profile.rig.path), seed=1, baud=921600)
    killer = threading.Timer(1.5, tr.proc.kill)
    killer.start()
    try:
        result = run_profile(profile, Session(tr), tmp_path / "drop.mcap", RunOptions())
    finally:
        killer.cancel()
        tr.close()
    assert result.error, "a dropped link must be reported"
    log = read_log(tmp_path / "drop.mcap")
    assert log.topic("/pmsm/telemetry")["t_s"].size > 100
    assert any("link error" in t or "silent" in t for t in log.topic("/pmsm/events")["text"])


def test_dc_link_over_voltage_trips_at_once(data, tmp_path):
    out = tmp_path / "ov.mcap"
    _, result = run_with_plant(data / "short.yaml", out, v_dc_v=800.0)
    assert result.state == "fault"
    assert result.faults & FAULT_BITS["dc_over_voltage"]
    assert not result.faults & FAULT_BITS["dc_under_voltage"]


def test_over_speed_trips(data, tmp_path, root):
    """A plant whose inertia is a hundred times smaller than the motor file's: the speed loop,
    designed for the nominal inertia, overshoots a step far past the trip speed."""
    prof = tmp_path / "fast.yaml"
    prof.write_text(
        f"name: fast\nmotor: {root}/profiles/motors/paper-a-ipmsm.yaml\n"
        f"rig: {root}/profiles/rigs/ideal.yaml\n"
        "segments:\n  - {duration_s: 0.5, speed_rpm: 1500, ramp_rpm_s: 0}\n"
    )
    out = tmp_path / "os.mcap"
    _, result = run_with_plant(prof, out, j_kgm2=0.0036 / 100.0)
    assert result.state == "fault"
    assert result.faults & FAULT_BITS["over_speed"], result.faults


def test_report_state_times_a_change_the_host_commands(data):
    """`emulate --report-state`: a change a command makes between control periods (the host's
    stop on Ctrl-C, its start) is printed at the device time it was made, not at the time of the
    change before it (a stop 0.5 s into the run read t_s=0.000050)."""
    import io

    from pmsm_hil.emulator.server import StateReporter
    from pmsm_hil.runner import configure

    profile = load_profile(str(data / "short.yaml"))
    settings = emulator_settings(profile.motor, profile.rig, seed=1, baud=profile.link.baud)
    link = InProcessTransport(settings)
    out = io.StringIO()
    reporter = StateReporter(link.dev, out)
    session = Session(link)
    session.hello()
    configure(session, profile)
    session.request("start")
    while link.dev.isr_count < 10000:  # 0.5 s of device time
        link.read(0.0)
        reporter.poll()
    isr, hb = link.dev.isr_count, link.dev.heartbeat_isr
    session.send("stop")  # taken by the firmware at once, before the next control period
    reporter.poll()
    ts = profile.control.ts_s
    assert out.getvalue().splitlines()[-1] == (
        f"state: stopping t_s={isr * ts:.6f} since_heartbeat_s={(isr - hb) * ts:.6f}"
    )
