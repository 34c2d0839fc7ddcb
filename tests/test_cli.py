"""The command line as a user meets it: runs, bad input, bad links, Ctrl-C."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

import pytest
from cli_helpers import CLI
from emu_helpers import emulator_children

from pmsm_hil.log.reader import read_log
from pmsm_hil.protocol import codec
from pmsm_hil.protocol import generated as gen


def cli(*args, timeout=180, **kw):
    return subprocess.run(
        [*CLI, *map(str, args)], capture_output=True, text=True, timeout=timeout, **kw
    )


def test_run_on_the_emulator_writes_a_log_and_a_summary(data, tmp_path):
    out = tmp_path / "short.mcap"
    r = cli("run", data / "short.yaml", "--out", out, "--no-live")
    assert r.returncode == 0, r.stderr
    assert f"log: {out}" in r.stdout
    assert "run summary" in r.stdout
    assert "all plateaus within bounds" in r.stdout
    log = read_log(out)
    assert len(log.topic("/pmsm/telemetry")["t_s"]) > 5000
    a = cli("analyze", out)
    assert a.returncode == 0 and "load on" in a.stdout


def test_an_mcap_file_of_another_program_is_named_as_such(tmp_path):
    """analyze and report of a valid MCAP file with none of pmsm-hil's topics (a ROS bag, another
    logger) say so and list its topics, rather than "no telemetry ... cut off"."""
    from mcap.writer import Writer

    other = tmp_path / "other.mcap"
    with open(other, "wb") as f:
        w = Writer(f)
        w.start()
        schema = w.register_schema("Pose", "jsonschema", b"{}")
        for i, topic in enumerate(("/tf", "/odom")):
            w.add_message(w.register_channel(topic, "json", schema), i, b"{}", i)
        w.finish()
    for cmd in ("analyze", "report"):
        r = cli(cmd, other, timeout=60)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert "an MCAP file of another program (topics: /odom, /tf), not a pmsm-hil log" in (
            r.stderr
        ), cmd
        assert "no telemetry" not in r.stderr


def test_bad_profile_names_file_line_field(tmp_path, root):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        f"name: bad\nmotor: {root}/profiles/motors/paper-a-ipmsm.yaml\nsegments:\n"
        "  - {duration_s: 1.0, speed_rpm: 9000, load_nm: 0}\n"
    )
    r = cli("run", bad, "--no-live")
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "bad.yaml:4" in r.stderr and "speed_rpm" in r.stderr and "9000" in r.stderr


def test_missing_profile_file(tmp_path):
    r = cli("run", tmp_path / "nope.yaml", "--no-live")
    assert r.returncode == 2
    assert "nope.yaml" in r.stderr and "Traceback" not in r.stderr


def test_port_that_does_not_exist(data):
    r = cli("run", data / "short.yaml", "--port", "/dev/ttyNOPE0", "--no-live")
    assert r.returncode == 3
    assert "/dev/ttyNOPE0 does not exist" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_port_that_is_no_serial_port(data, tmp_path):
    """A device or file that is no terminal (`/dev/null`, a log given by mistake): said as such,
    not as pyserial's "Could not configure port: (25, 'Inappropriate ioctl for device')"."""
    a_file = tmp_path / "not-a-port"
    a_file.write_text("")
    for port in ("/dev/null", str(a_file)):
        r = cli("run", data / "short.yaml", "--port", port, "--no-live", "--out", "x.mcap")
        assert r.returncode == 3, r.stderr
        assert f"{port} is not a serial port" in r.stderr and "ioctl" not in r.stderr
        assert "Traceback" not in r.stderr


def _pty():
    master, slave = os.openpty()
    tty.setraw(slave)
    return master, slave, os.ttyname(slave)


def test_device_that_does_not_answer(data):
    master, slave, path = _pty()
    try:
        r = cli("run", data / "short.yaml", "--port", path, "--no-live", timeout=60)
    finally:
        os.close(master)
        os.close(slave)
    assert r.returncode == 3
    assert "no answer to hello" in r.stderr and path in r.stderr
    assert "Traceback" not in r.stderr


def test_protocol_mismatch_is_refused_naming_both_versions(data):
    master, slave, path = _pty()
    stop = threading.Event()

    def fake_device():
        dec = codec.FrameDecoder()
        while not stop.is_set():
            try:
                chunk = os.read(master, 4096)
            except OSError:
                return
            for fr in dec.feed(chunk):
                if fr.name == "hello":
                    os.write(
                        master,
                        codec.encode(
                            "identify",
                            0,
                            proto_version=gen.PROTOCOL_VERSION + 1,
                            schema_hash=0x12345678,
                            fw_major=9,
                            fw_minor=0,
                            fw_patch=0,
                            board=1,
                            tx_buf_octets=1024,
                            capture_len=1024,
                        ),
                    )

    th = threading.Thread(target=fake_device, daemon=True)
    th.start()
    try:
        r = cli("run", data / "short.yaml", "--port", path, "--no-live", timeout=60)
    finally:
        stop.set()
        os.close(slave)
        os.close(master)
    assert r.returncode == 3
    assert "protocol mismatch" in r.stderr
    assert f"version {gen.PROTOCOL_VERSION + 1}" in r.stderr and "12345678" in r.stderr
    assert f"version {gen.PROTOCOL_VERSION}" in r.stderr and f"{gen.SCHEMA_HASH:08x}" in r.stderr


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_ctrl_c_stops_the_motor_and_keeps_the_log(data, tmp_path, signame):
    """Ctrl-C typed in a terminal: SIGINT goes to the whole foreground process group; a `kill`
    sends SIGTERM to the process alone, and the run says which it was."""
    out = tmp_path / "int.mcap"
    p = subprocess.Popen(
        [*CLI, "run", str(data / "long.yaml"), "--out", str(out), "--no-live"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    # wait until the run streams (progress lines), then interrupt
    deadline = time.monotonic() + 60
    seen = ""
    while time.monotonic() < deadline:
        line = p.stdout.readline()
        seen += line
        if line.startswith("t=") and "running" in line:
            break
    time.sleep(0.5)
    children = emulator_children(p.pid)
    assert children, "the run should have started an emulator process"
    if signame == "SIGINT":
        os.killpg(p.pid, signal.SIGINT)  # the group: what the terminal does
    else:
        os.kill(p.pid, signal.SIGTERM)
    stdout, stderr = p.communicate(timeout=60)
    assert p.returncode == 130, stderr
    by = "" if signame == "SIGINT" else " by SIGTERM"
    assert f"interrupted{by}: stopping the motor (Ctrl-C again to abort)" in stdout + stderr
    assert "Traceback" not in stderr and "link" not in stderr
    assert "INCOMPLETE" in stdout and "run interrupted" in stdout
    assert "all plateaus within bounds" not in stdout
    log = read_log(out)
    assert log.finalised
    from mcap.reader import make_reader

    with open(out, "rb") as f:  # the generic reader, through the file's index
        n_generic = sum(1 for _ in make_reader(f).iter_messages())
    assert n_generic == sum(log.counts.values())
    kinds = list(log.topic("/pmsm/events")["kind"])
    texts = list(log.topic("/pmsm/events")["text"])
    assert "stopped" in kinds
    assert any("host stop" in t for t in texts)
    assert any(f"interrupted by {signame}" in t for t in texts)
    tel = log.topic("/pmsm/telemetry")
    assert abs(tel["speed_rpm"][-1]) < 5.0
    for c in children:  # the host ended its emulator
        assert (
            not os.path.exists(f"/proc/{c}")
            or Path(f"/proc/{c}/stat").read_text().split()[2] == "Z"
        )


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_a_kill_before_the_stream_is_an_interrupt(data, tmp_path, monkeypatch, capsys, signame):
    """SIGTERM or SIGHUP before the stream (the emulator child started and answering, the run's
    modules loading) is a Ctrl-C: exit 130 with one line, the child ended with the link, no log
    begun, and the caller's handler back afterwards (the default action used to end the process
    with -15 and nothing said, the child left to notice on its own)."""
    from pmsm_hil import device
    from pmsm_hil.cli import run
    from pmsm_hil.cli.main import main

    sig = getattr(signal, signame)
    opened = []
    real = device.open_device

    def open_device(spec, profile):
        opened.append(real(spec, profile))
        return opened[-1]

    def killed(collecting):  # where the run's modules are in: before its own handlers
        os.kill(os.getpid(), sig)

    monkeypatch.setattr(device, "open_device", open_device)
    monkeypatch.setattr(run, "_settle", killed)
    # as in a terminal: the signal at its default action (a suite run under nohup inherits
    # SIGHUP ignored, which the command then keeps)
    inherited = signal.signal(sig, signal.SIG_DFL)
    out = tmp_path / "k.mcap"
    try:
        assert main(["run", str(data / "short.yaml"), "--out", str(out), "--no-live"]) == 130
        assert signal.getsignal(sig) is signal.SIG_DFL  # the caller's handler back
    finally:
        signal.signal(sig, inherited)
    assert "pmsm-hil run: interrupted" in capsys.readouterr().err
    assert not out.exists()
    (link,) = opened
    assert link.transport.proc.poll() is not None  # the emulator child, ended with the link


def test_emulate_serves_a_pty_that_run_uses_like_a_rig(data, tmp_path):
    emu = subprocess.Popen(
        [*CLI, "emulate", "--seed", "3"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        line = emu.stdout.readline()
        assert line.startswith("serial: /dev/"), line
        port = line.split()[1]
        out = tmp_path / "rig.mcap"
        r = cli("run", data / "short.yaml", "--port", port, "--out", out, "--no-live")
        assert r.returncode == 0, r.stderr
        assert read_log(out).metadata["device"]["board"] == "emulator"
    finally:
        emu.send_signal(signal.SIGTERM)
        emu.wait(timeout=10)
    assert emu.returncode == 0


def test_corrupted_link_is_counted_dropped_and_resynchronised(data, tmp_path):
    from pmsm_hil.profiles import load_profile
    from pmsm_hil.protocol.session import Session
    from pmsm_hil.runner import RunOptions, run_profile
    from pmsm_hil.transport.emulator import EmulatorTransport

    profile = load_profile(str(data / "short.yaml"))
    tr = EmulatorTransport(
        str(profile.motor.path), str(profile.rig.path), seed=1, baud=921600, corrupt_ppm=300
    )
    try:
        result = run_profile(profile, Session(tr), tmp_path / "noisy.mcap", RunOptions())
    finally:
        tr.close()
    assert result.state == "done" and result.faults == 0
    assert result.live.bad_frames > 0
    tel = read_log(tmp_path / "noisy.mcap").topic("/pmsm/telemetry")
    # most frames made it, and the ones that did are intact (t_s on the 0.5 ms grid)
    assert len(tel["t_s"]) > 0.9 * profile.total_duration_s * 2000
    assert pytest.approx(0.0, abs=1e-9) == float(
        max(abs((tel["t_s"] * 2000) - (tel["t_s"] * 2000).round()))
    )
    a = cli("analyze", tmp_path / "noisy.mcap")  # the loss is reported, not hidden
    assert a.returncode == 1 and "lost frames on the link" in a.stdout and "INCOMPLETE" in a.stdout


def test_port_that_is_busy(data):
    import serial

    master, slave, path = _pty()
    holder = serial.Serial(path, exclusive=True)
    try:
        r = cli("run", data / "short.yaml", "--port", path, "--no-live", timeout=60)
    finally:
        holder.close()
        os.close(master)
        os.close(slave)
    assert r.returncode == 3
    assert f"serial port {path} is busy" in r.stderr
    assert "Traceback" not in r.stderr


def test_only_a_command_that_ends_clean_skips_the_interpreters_teardown(data, tmp_path):
    """entry(): `run` returns with its log closed and its emulator child waited for, so the
    process ends at once (os._exit with run's code, stdout flushed first); a command without
    ENDS_CLEAN (here `profiles`) keeps the ordinary exit, and so does a run beside a non-daemon
    thread (the interpreter waits for it). In a fresh interpreter each: other tests' threads are
    not this process's."""
    out = tmp_path / "short.mcap"
    script = (
        "import os, sys, threading\n"
        "from pmsm_hil.cli import main as m\n"
        "def fake(code):\n"
        "    print(f'os._exit {code}', flush=True)\n"
        "    raise SystemExit(code)\n"
        "m.os._exit = fake\n"
        "sys.argv = ['pmsm-hil', *sys.argv[1:]]\n"
        "done = threading.Event()\n"
        "if os.environ.get('KEEP_THREAD'):  # not a daemon, alive until entry() has returned\n"
        "    threading.Thread(target=done.wait, args=(20.0,)).start()\n"
        "print('returned', m.entry(), flush=True)\n"
        "done.set()\n"
    )

    def entry(*args, **env):
        return subprocess.run(
            [sys.executable, "-c", script, *map(str, args)],
            capture_output=True,
            text=True,
            timeout=120,
            env={**os.environ, **env},
        )

    short = ("run", data / "short.yaml", "--no-live", "--overwrite", "--out", out)
    r = entry(*short, "--stop-after", "0.2")
    assert r.returncode == 0 and "os._exit 0" in r.stdout and "returned" not in r.stdout, r.stderr
    assert "log: " in r.stdout  # the summary was flushed before the process ended
    assert read_log(out).counts["/pmsm/telemetry"] > 100  # closed: read as a finished log
    r = entry("run", tmp_path / "missing.yaml")  # refused before it started: as clean
    assert r.returncode == 2 and "os._exit 2" in r.stdout
    r = entry("profiles")
    assert "returned 0" in r.stdout and "os._exit" not in r.stdout
    r = entry(*short, "--stop-after", "0.1", KEEP_THREAD="1")
    assert "returned 0" in r.stdout and "os._exit" not in r.stdout, r.stdout
