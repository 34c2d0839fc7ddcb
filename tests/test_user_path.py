"""The everyday path as a new user meets it (shipped names: tests/test_shipped_files.py): the
emulator child's imports, bad output paths, closed pipes, the link budget, truncated and empty logs, pace, wall-clock log times."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_helpers import CLI, cli
from emu_helpers import run_inproc
from mcap.reader import make_reader

from pmsm_hil.emulator.server import Pacer
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.profiles.shipped import resolve
from pmsm_hil.protocol import generated as gen


def test_two_runs_started_in_the_same_second_keep_their_own_logs(tmp_path, monkeypatch):
    from pmsm_hil.cli import run as run_cli

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(run_cli.time, "strftime", lambda fmt: "20261128-120000")
    paths = [run_cli.default_log_path("profiles/paper-b.yaml") for _ in range(3)]
    assert [p.name for p in paths] == [
        "paper-b-20261128-120000.mcap",
        "paper-b-20261128-120000-2.mcap",
        "paper-b-20261128-120000-3.mcap",
    ]
    assert all(p.is_file() for p in paths)  # each made for its run: no other run takes it


def test_stop_after_must_be_a_positive_time(data, tmp_path):
    r = cli("run", data / "short.yaml", "--stop-after", -5, "--no-live", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "--stop-after -5.0: must be a positive device time" in r.stderr
    assert not (tmp_path / "runs").exists()


def test_emulator_child_ignores_a_source_tree_in_the_working_directory(tmp_path, data):
    """The fresh-clone failure: a `pmsm_hil` folder without the compiled extension in the working
    directory must not shadow the installed package in the emulator child."""
    shadow = tmp_path / "pmsm_hil"
    shadow.mkdir()
    (shadow / "__init__.py").write_text(
        "raise ImportError('the source tree shadowed the install')\n"
    )
    (shadow / "emulator").mkdir()
    (shadow / "emulator" / "__init__.py").write_text("")
    from pmsm_hil.transport.emulator import EmulatorTransport

    profile = load_profile(str(data / "short.yaml"))
    tr = EmulatorTransport(str(profile.motor.path), str(profile.rig.path), seed=1, baud=921600)
    try:
        assert tr.name.startswith("emulator /dev/")
        assert tr.proc.poll() is None
        assert os.getsid(tr.proc.pid) == tr.proc.pid  # a session of its own: no terminal SIGINT
    finally:
        tr.close()


def test_an_emulator_the_os_will_not_start_is_a_link_error_and_leaves_no_child(
    data, tmp_path, monkeypatch, capsys
):
    """An OSError while the child starts (fork refused, EFAULT once seen under load) is the
    link's error (exit 3, one line), not a traceback; a child already started is stopped."""
    from pmsm_hil.cli.main import main
    from pmsm_hil.emulator import process as emu_process
    from pmsm_hil.errors import TransportError
    from pmsm_hil.transport.emulator import EmulatorTransport

    def refused(args):
        raise OSError(14, "Bad address")

    monkeypatch.setattr(emu_process, "start", refused)
    assert main(["run", str(data / "short.yaml"), "--no-live", "--out", "x.mcap"]) == 3
    err = capsys.readouterr().err
    assert "the emulator could not be started: Bad address (errno 14)" in err
    assert "Traceback" not in err
    monkeypatch.undo()
    started = []

    def lost(proc, prefix, timeout_s):
        started.append(proc)
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(emu_process, "wait_for_announcement", lost)
    profile = load_profile(str(data / "short.yaml"))
    with pytest.raises(TransportError, match="could not be started: Input/output error"):
        EmulatorTransport(str(profile.motor.path), str(profile.rig.path), seed=1, baud=921600)
    assert len(started) == 1 and started[0].poll() is not None  # stopped, not left running
    monkeypatch.undo()
    # the child serves, its pty cannot be opened: the error says which stage failed
    from pmsm_hil.transport import serial_port

    def unopenable(self, port, baud):
        raise OSError(14, "Bad address")

    start = emu_process.start
    monkeypatch.setattr(
        emu_process, "start", lambda args: started.append(start(args)) or started[-1]
    )
    monkeypatch.setattr(serial_port.SerialTransport, "__init__", unopenable)
    with pytest.raises(
        TransportError, match=r"emulator's pty /dev/\S+ could not be opened: Bad"
    ) as e:
        EmulatorTransport(str(profile.motor.path), str(profile.rig.path), seed=1, baud=921600)
    assert "(errno 14)" in str(e.value)
    assert len(started) == 2 and started[1].poll() is not None  # the child stopped


def test_emulate_takes_the_plant_from_a_profile():
    p = subprocess.Popen(
        [*CLI, "emulate", "--profile", "sew-cm3c80s"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert p.stdout.readline().startswith("serial: /dev/")
        assert "motor: sew-cm3c80s" in p.stdout.readline()
    finally:
        p.terminate()
        p.wait(timeout=10)
    r = cli("emulate", "--rig", "no-such-rig")
    assert r.returncode == 2 and "no-such-rig" in r.stderr and "Traceback" not in r.stderr


# ----------------------------------------------------------------------------- user-side errors


def test_unwritable_out_is_bad_input(tmp_path, data):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = cli("run", data / "short.yaml", "--out", blocker / "run.mcap", "--no-live")
    assert r.returncode == 2
    assert "cannot write there" in r.stderr and str(blocker) in r.stderr
    assert "Traceback" not in r.stderr


def test_an_existing_log_is_kept_and_a_folder_is_named_as_one(tmp_path, data):
    old = tmp_path / "old.mcap"
    old.write_bytes(b"the log of an earlier run")
    r = cli("run", data / "short.yaml", "--out", old, "--no-live")
    assert r.returncode == 2 and "a log is there already; --overwrite replaces it" in r.stderr
    assert old.read_bytes() == b"the log of an earlier run"
    r = cli("run", data / "short.yaml", "--out", tmp_path, "--no-live")
    assert r.returncode == 2 and "is a directory; give the log's file name" in r.stderr


@pytest.mark.parametrize("spec", ["bogus", "nosuchbus:can0", "socketcand:x"])
def test_bad_can_spec_is_bad_input(data, spec, tmp_path):
    r = cli("run", data / "short.yaml", "--can", spec, "--out", tmp_path / "x.mcap", "--no-live")
    assert r.returncode == 2, r.stderr
    assert spec in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "x.mcap").exists()


def test_closed_pipe_gives_no_traceback(data, tmp_path):
    out = tmp_path / "pipe.mcap"
    sh = f"{sys.executable} -m pmsm_hil.cli.main run {data / 'short.yaml'} --no-live --out {out} | head -n 1"
    r = subprocess.run(
        ["bash", "-o", "pipefail", "-c", sh], capture_output=True, text=True, timeout=180
    )
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr and "BrokenPipe" not in r.stderr
    assert len(r.stdout.splitlines()) == 1
    log = read_log(out)
    assert log.finalised and "profile_done" in list(log.topic("/pmsm/events")["kind"])


def test_a_link_that_cannot_carry_the_telemetry_is_refused_with_the_budget(data, tmp_path):
    out = tmp_path / "slow.mcap"
    r = cli("run", data / "short.yaml", "--baud", 115200, "--out", out, "--no-live")
    assert r.returncode == 2
    assert "cannot carry" in r.stderr and "link budget at 115200 baud" in r.stderr
    assert "telem_fast" in r.stderr and "--decimate" in r.stderr
    assert not out.exists()
    r = cli("run", data / "short.yaml", "--baud", 115200, "--decimate", "--out", out, "--no-live")
    assert r.returncode == 0, r.stderr
    assert "decimated from 2000 Hz" in r.stderr
    tel = read_log(out).topic("/pmsm/telemetry")
    rate = (len(tel["t_s"]) - 1) / (tel["t_s"][-1] - tel["t_s"][0])
    assert rate < 115200 / 10 / 27  # fewer fast frames than the link could carry alone
    assert read_log(out).counts.get("/pmsm/status", 0) > 0


# ----------------------------------------------------------------------------- logs


@pytest.fixture(scope="module")
def short_log(tmp_path_factory):
    out = tmp_path_factory.mktemp("logs") / "short.mcap"
    run_inproc(Path(__file__).parent / "data" / "short.yaml", out)
    return out


def test_log_time_is_wall_clock_and_t_s_device_time(short_log):
    log = read_log(short_log)
    lt = log.log_times_ns("/pmsm/telemetry").astype("int64")
    t = log.topic("/pmsm/telemetry")["t_s"]
    offset = int(log.metadata["log"]["log_time_offset_ns"])
    assert abs(offset / 1e9 - time.time()) < 3600  # a real date: the run's start
    assert ((lt - offset) == (t * 1e9).round().astype("int64")).all()
    with open(short_log, "rb") as f:  # the generic reader agrees
        msgs = list(make_reader(f).iter_messages(topics=["/pmsm/telemetry"]))
    assert msgs[0][2].log_time == lt[0]


def test_analyze_a_truncated_log_says_what_is_missing(short_log, tmp_path):
    data = short_log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 3])
    r = cli("analyze", cut)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "INCOMPLETE" in r.stdout and "truncated" in r.stdout
    assert "all plateaus within bounds" not in r.stdout
    assert "messages recovered" in r.stdout
    assert "missing" in r.stdout or "partial" in r.stdout
    import json

    j = json.loads(cli("analyze", cut, "--json").stdout)
    assert j["complete"] is False and j["ok"] is False and j["problems"]


def test_analyze_an_empty_or_foreign_file_is_an_error(tmp_path):
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    r = cli("analyze", empty)
    assert r.returncode == 2 and "empty" in r.stderr and "Traceback" not in r.stderr
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    r = cli("analyze", junk)
    assert r.returncode == 2 and "not an MCAP file" in r.stderr


def test_analyze_a_complete_log_passes(short_log):
    r = cli("analyze", short_log)
    assert r.returncode == 0, r.stdout
    assert "all plateaus within bounds" in r.stdout


def test_identification_table_in_the_run_summary(tmp_path, root):
    ident = root / "profiles" / "paper-a-identify.yaml"
    out = tmp_path / "id.mcap"
    r = cli("run", ident, "--out", out, "--no-live", "--stop-after", 1.2, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "NLMS" in r.stdout or "nlms" in r.stdout


# ----------------------------------------------------------------------------- pace


class _FakeDevice:
    def __init__(self, ts_s=50e-6):
        self.values = {"ts_s": ts_s, "heartbeat_timeout_s": 0.5}
        self.isr_count = 0
        self.heartbeat_isr = 0

    def get(self, key):
        return self.values[key]


@pytest.mark.parametrize("pace", [0.5, 1.0, 4.0])
def test_pace_holds_device_time_to_x_times_wall_time(pace):
    dev = _FakeDevice()
    pacer = Pacer(pace=pace)
    now = 100.0
    for _ in range(2000):  # 2 s of wall time in 1 ms steps, host always current
        n = pacer.allowance(dev, now)
        dev.isr_count += n
        dev.heartbeat_isr = dev.isr_count
        now += 0.001
    device_s = dev.isr_count * dev.get("ts_s")
    assert device_s == pytest.approx(pace * 2.0, rel=0.01)


def test_without_pace_the_heartbeat_lead_is_the_only_limit():
    dev = _FakeDevice()
    n = Pacer().allowance(dev, 0.0)
    assert n == 1000  # one chunk at once, far faster than real time


def test_run_with_pace_one_runs_in_real_time(data, tmp_path):
    out = tmp_path / "paced.mcap"
    t0 = time.monotonic()
    r = cli("run", data / "short.yaml", "--pace", 1, "--stop-after", 1.0, "--out", out, "--no-live")
    wall = time.monotonic() - t0
    assert r.returncode == 0, r.stderr
    device_s = read_log(out).topic("/pmsm/telemetry")["t_s"][-1]
    assert wall >= 0.9 * device_s  # never faster than real time (slower on a loaded machine)
    r = cli("run", data / "short.yaml", "--pace", 0)
    assert r.returncode == 2 and "--pace" in r.stderr


def test_can_run_keeps_python_can_chatter_off_the_terminal(data, tmp_path):
    out = tmp_path / "can.mcap"
    r = cli("run", data / "short.yaml", "--can", "--out", out, "--no-live")
    assert r.returncode == 0, r.stderr
    assert "incomplete message" not in r.stderr and "WARNING" not in r.stderr
    log = read_log(out)
    assert log.finalised
    # the fast telemetry was lowered to fit the bus: said, at the rate the log then holds
    note = next(line for line in r.stderr.splitlines() if line.startswith("note: telemetry."))
    hz = float(note.split("telemetry.fast_hz ")[1].split(" Hz")[0])
    assert "over CAN at 1000 kbit/s, not the profile's 2000 Hz" in note and hz < 2000
    t = log.topic("/pmsm/telemetry")["t_s"]
    assert len(t) / (t[-1] - t[0]) == pytest.approx(hz, rel=0.02)


def test_summary_fits_80_columns_by_leaving_out_columns(short_log):
    from rich.console import Console

    from pmsm_hil.analysis.summary import summarize_log
    from pmsm_hil.analysis.summary_text import print_summary

    console = Console(width=80, record=True, force_terminal=False)
    print_summary(summarize_log(short_log), console)
    text = console.export_text()
    assert "…" not in text
    assert max(len(line) for line in text.splitlines()) <= 80
    assert "load on" in text and "not shown at 80 columns" in text
    wide = Console(width=200, record=True)
    print_summary(summarize_log(short_log), wide)
    wide_text = wide.export_text()
    assert "not shown" not in wide_text and "ripple d/q A" in wide_text


def test_a_run_against_an_emulator_of_another_motor_says_so(tmp_path):
    """A SEW profile against an emulator serving paper A's motor: named, not a bare DC-link fault."""
    emu = subprocess.Popen(
        [*CLI, "emulate"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        port = emu.stdout.readline().split()[1]
        r = cli("run", "sew-cm3c80s", "--port", port, "--out", tmp_path / "sew.mcap", "--no-live")
        assert r.returncode == 2, r.stderr
        assert "not this profile's motor" in r.stderr and "psi_f_wb" in r.stderr
        assert "emulate --profile" in r.stderr
        r = cli(
            "run",
            "paper-a",
            "--port",
            port,
            "--out",
            tmp_path / "pa.mcap",
            "--no-live",
            "--stop-after",
            0.3,
        )
        assert r.returncode == 0, r.stderr  # the emulator serves on, and its own motor runs
    finally:
        emu.terminate()
        emu.wait(timeout=10)


def test_a_lost_stopped_event_still_ends_the_run_cleanly(tmp_path, monkeypatch):
    """One lost event frame must not fail a good run: the status frames show the stop."""
    from pmsm_hil.recorder import Recorder

    real = Recorder._on_event

    def drop_stopped(self, f):
        if f["code"] == gen.ENUMS["event"]["stopped"]:
            return  # the frame carrying `stopped` is lost
        real(self, f)

    monkeypatch.setattr(Recorder, "_on_event", drop_stopped)
    out = tmp_path / "lost.mcap"
    _, result = run_inproc(Path(__file__).parent / "data" / "short.yaml", out)
    assert not result.error and result.stop_reason == "profile end"
    assert result.capture_samples > 0  # the capture was still uploaded
    texts = list(read_log(out).topic("/pmsm/events")["text"])
    assert any("stopped event did not arrive" in t for t in texts)


def test_a_yaml_alias_bomb_is_refused_at_once(tmp_path):
    rows = ['a: &a ["x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    for prev, name in zip("abcdefgh", "bcdefghi", strict=False):
        rows.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 9) + "]")
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(rows) + "\n")  # 9^9 values once expanded
    r = cli("run", bomb, timeout=30)
    assert r.returncode == 2 and "alias" in r.stderr and "Traceback" not in r.stderr


def test_can_run_with_the_live_view_on_a_terminal(data, tmp_path):
    """The live view renders on a terminal (a pty here) while CAN streams: it must never starve
    the link (heartbeat) nor end the run."""
    import pty
    import select

    master, slave = pty.openpty()
    out = tmp_path / "live-can.mcap"
    p = subprocess.Popen(
        [*CLI, "run", str(data / "short.yaml"), "--can", "--out", str(out)],
        stdout=slave,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        env={**os.environ, "COLUMNS": "80", "LINES": "24"},
    )
    os.close(slave)
    screen = b""
    while p.poll() is None:
        if select.select([master], [], [], 0.1)[0]:
            try:
                screen += os.read(master, 65536)
            except OSError:
                break
    p.wait(timeout=180)
    os.close(master)
    assert p.returncode == 0, p.stderr.read()
    assert b"state" in screen  # the live view was drawn
    log = read_log(out)
    assert log.finalised and "profile_done" in list(log.topic("/pmsm/events")["kind"])


def test_the_emulator_child_takes_the_hosts_settings_and_imports_no_profile_loader(tmp_path):
    """The host builds the sim board's settings (it has loaded the files already) and hands them
    over in a file: the child reads neither motor nor rig and imports no pydantic, nor numpy on a
    clean line (the link noise's generator is only needed with --corrupt-ppm/--drop-ppm)."""
    from pmsm_hil.device import DeviceSpec, _child_settings

    profile = load_profile(
        resolve("paper-a", "profile"), rig_override=resolve("lab-typical", "rig")
    )
    settings, plant = _child_settings(
        DeviceSpec(rig_path=resolve("lab-typical", "rig")), profile, 921600
    )
    assert "rig: lab-typical" in plant and isinstance(settings["sat_psi_d_wb"], list)
    f = tmp_path / "settings.json"
    import json

    f.write_text(json.dumps({"settings": settings, "plant": plant}))
    p = subprocess.Popen(
        [sys.executable, "-X", "importtime", "-m", "pmsm_hil.emulator", "--settings-file", str(f)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert p.stdout.readline().startswith("serial: /dev/")
        assert p.stdout.readline().strip() == plant
    finally:
        p.terminate()
        _, err = p.communicate(timeout=10)
    imported = {line.split("|")[-1].strip() for line in err.splitlines() if "|" in line}
    assert "pmsm_hil.emulator.fwlib" in imported
    assert not {m for m in imported if m.startswith(("pydantic", "pmsm_hil.profiles", "numpy"))}
    f.write_text("{not json")
    r = cli("emulate", "--settings-file", f)
    assert r.returncode == 2 and "settings.json" in r.stderr and "Traceback" not in r.stderr


def test_a_host_slower_than_a_paced_device_still_keeps_its_heartbeat(data, tmp_path, monkeypatch):
    """`run --pace 20 --foxglove`: the device times out after 25 ms of wall time without a
    heartbeat, and a receive batch (up to 64 KiB, some 1800 frames) through a Foxglove sink took
    longer than that to record, so the run faulted with "heartbeat lost" though the host was
    there. The batch is recorded in slices with a heartbeat between them. Here at --pace 5 (the
    device waits 100 ms) with a sink of 100 us a message: a whole batch took some 200 ms, a slice
    of 256 takes 30 ms; the motor is no longer stopped, and what the host cannot keep up with is
    lost on the link, as on a rig."""
    from pmsm_hil.cli.main import main
    from pmsm_hil.live import foxglove

    class SlowSink:
        url = "ws://127.0.0.1:0"

        def __init__(self, port):
            pass

        def publish(self, topic, t_s, fields):
            end = time.perf_counter() + 100e-6
            while time.perf_counter() < end:
                pass

        def close(self):
            pass

    monkeypatch.setattr(foxglove, "FoxgloveSink", SlowSink)
    out = tmp_path / "slow-host.mcap"
    args = ["run", str(data / "short.yaml"), "--no-live", "--pace", "5", "--out", str(out)]
    code = main([*args, "--stop-after", "1.5", "--foxglove", "1"])
    texts = [str(t) for t in read_log(out).topic("/pmsm/events")["text"]]
    assert not any("heartbeat" in t for t in texts), texts
    assert code == 0
