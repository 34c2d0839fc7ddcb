"""A host that dies or freezes mid-run on the serial emulator: the device's clock runs on (its UART
output is dropped as a full FIFO would) and its heartbeat timeout stops the motor, measured in
device time from the emulator's own state."""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from emu_helpers import emulator_children, served_on_pty

from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import generated as gen
from pmsm_hil.runner import LOG_FLUSH_WALL_S

STATE = gen.ENUMS["state"]
_RUN = [sys.executable, "-m", "pmsm_hil.cli.main", "run", "--no-live"]


def _wait_running(dev, profile, after_s: float = 1.0) -> None:
    """Until the served device has run ``after_s`` of device time (at most 60 s of wall time)."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (
        dev.state == STATE["running"] and dev.isr_count * profile.control.ts_s > after_s
    ):
        time.sleep(0.01)


@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGSTOP])
def test_lost_host_on_serial_stops_the_motor_within_the_heartbeat_time(data, tmp_path, how):
    profile = load_profile(str(data / "long.yaml"))
    lost = tmp_path / "lost.mcap"
    with served_on_pty(profile) as (dev, server):
        host = subprocess.Popen(
            [*_RUN, "--port", server.path, str(data / "long.yaml"), "--out", str(lost)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            _wait_running(dev, profile)
            assert dev.state == STATE["running"], "the run never started"
            os.kill(host.pid, how)
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline and dev.state == STATE["running"]:
                time.sleep(0.002)
            assert dev.state != STATE["running"], "the motor kept running without its host"
            ts = profile.control.ts_s
            silent_s = (dev.isr_count - dev.heartbeat_isr) * ts  # device time since the heartbeat
            assert silent_s <= profile.control.heartbeat_timeout_s + 0.01  # + this loop's sampling
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline and dev.active:
                time.sleep(0.01)
            assert dev.state == STATE["idle"]  # brought to rest, PWM off
        finally:
            if how == signal.SIGSTOP:
                os.kill(host.pid, signal.SIGKILL)
            host.wait(timeout=10)


def test_a_killed_hosts_log_holds_every_message_it_had_received(data, tmp_path):
    """SIGKILL right after a progress line: every device message the host had received by then
    (the line's frame count) is on disk, in the log's chunks and its journal (LOG.journal), for
    the generic `mcap` reader: its stream reader on the two files as they are, and its indexed
    reader on the one file `log recover` makes of them."""
    from mcap.reader import make_reader
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader

    from pmsm_hil.log.journal import journal_path, read_journal
    from pmsm_hil.log.reader import read_log

    out = tmp_path / "killed.mcap"
    host = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pmsm_hil.cli.main",
            "run",
            str(data / "long.yaml"),
            "--pace",
            "1",
            "--out",
            str(out),
            "--no-live",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 60
    t_line, frames_line = 0.0, 0
    while time.monotonic() < deadline:
        line = host.stdout.readline()
        m = re.match(r"t=\s*([0-9.]+)/.* frames (\d+) ", line)
        if m and float(m.group(1)) >= 2.5:
            # printed after the batch that brought these frames was handed to the recorder
            t_line, frames_line = float(m.group(1)), int(m.group(2))
            break
    children = emulator_children(host.pid)
    assert children and t_line
    os.killpg(host.pid, signal.SIGKILL)  # at once: the host is mid-stream, paced at real time
    host.wait(timeout=10)
    deadline = time.monotonic() + 20  # its emulator stops the motor, then ends
    while time.monotonic() < deadline and any(os.path.exists(f"/proc/{c}") for c in children):
        time.sleep(0.05)
    assert not any(os.path.exists(f"/proc/{c}") for c in children), "the emulator outlived its host"
    log = read_log(out)
    assert not log.finalised
    n = sum(log.counts.values())
    seen = {}
    for path in (out, journal_path(out)):  # the generic stream reader, the files as they are
        # (the stream reader reports the missing footer at the end)
        with open(path, "rb") as f, contextlib.suppress(Exception):
            for rec in StreamReader(f).records:
                if isinstance(rec, Channel):
                    topics = seen.setdefault(path, {})
                    topics[rec.id] = rec.topic
                elif isinstance(rec, Message):
                    seen.setdefault((path, "n"), []).append(seen[path][rec.channel_id])
    assert len(seen[(out, "n")]) == n
    journal = read_journal(out, n)  # what the log's chunks do not hold
    # what came after the last chunk is in the journal; the kill can land just after a chunk was
    # written (a loaded machine), and then there is nothing after it yet
    assert len(journal) <= len(seen.get((journal_path(out), "n"), []))
    n_all = n + len(journal)
    device = ("/pmsm/", "/sim/")
    n_device = sum(t.startswith(device) for t in seen[(out, "n")]) + sum(
        m.topic.startswith(device) for m in journal
    )
    # each received frame of the stream is one device message (no acks while streaming), and
    # the host's own start event is one more
    assert n_device >= frames_line + 1, (n_device, frames_line)
    r = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", "log", "recover", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    assert f"{n} messages" in r.stdout
    n_tel = log.counts["/pmsm/telemetry"]
    assert f"/pmsm/telemetry: {n_tel} messages" in r.stdout
    if journal:
        assert f"{len(journal)} more messages, received after the last chunk" in r.stdout
    assert f"all {n_all} messages rewritten" in r.stdout
    assert "lost: none of the device's messages the host had received" in r.stdout
    assert f"last {LOG_FLUSH_WALL_S:g} s of wall time" in r.stdout  # the host's own events
    fixed = out.with_suffix(".recovered.mcap")
    offset_ns = int(log.metadata["log"]["log_time_offset_ns"])
    with open(fixed, "rb") as f:  # the generic reader's default path, through the index
        reader = make_reader(f)
        assert reader.get_summary() is not None
        msgs = [(c.topic, m.log_time) for _, c, m in reader.iter_messages()]
    assert len(msgs) == n_all
    assert sum(topic.startswith(device) for topic, _ in msgs) >= frames_line + 1
    tel = sorted(lt - offset_ns for topic, lt in msgs if topic == "/pmsm/telemetry")
    # up to the line's device time (printed to 0.01 s; the last message may be a status frame)
    assert tel[-1] / 1e9 >= t_line - 0.01
    steps = np.diff(tel)
    assert steps.max() <= 1.5 * np.median(steps)  # and none missing on the way
    assert (
        read_log(fixed).metadata["log"]["log_time_offset_ns"]
        == log.metadata["log"]["log_time_offset_ns"]
    )


def test_emulate_reports_when_a_killed_host_got_its_motor_stopped(data, tmp_path):
    """The emulator as a user serves it (`emulate --report-state`), the host killed with -9: the
    emulator's own report says the motor went to stopping within the heartbeat timeout."""
    emu = subprocess.Popen(
        [sys.executable, "-m", "pmsm_hil.cli.main", "emulate", "--report-state"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        port = emu.stdout.readline().split()[1]
        emu.stdout.readline()  # motor: ... rig: ...
        host = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "pmsm_hil.cli.main",
                "run",
                str(data / "long.yaml"),
                "--port",
                port,
                "--out",
                str(tmp_path / "k.mcap"),
                "--no-live",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        assert emu.stdout.readline().startswith("state: running")
        time.sleep(1.0)
        host.kill()
        host.wait(timeout=10)
        line = emu.stdout.readline()
        assert line.startswith("state: stopping"), line
        since = float(re.search(r"since_heartbeat_s=([0-9.]+)", line).group(1))
        assert since <= 0.5 + 50e-6 + 1e-9  # the heartbeat timeout + one period
        assert emu.stdout.readline().startswith("state: idle")  # brought to rest, PWM off
    finally:
        emu.terminate()
        emu.wait(timeout=10)


def test_a_killed_emulator_ends_the_run_with_a_clear_error_and_a_finalised_log(data, tmp_path):
    """The device side dies (the emulator child killed with -9, as a board that loses power or a
    cable pulled from a USB-serial adapter): the host does not hang, says the link dropped, exits
    3, and finalises the log with everything received up to then (the generic indexed reader)."""
    from mcap.reader import make_reader

    out = tmp_path / "device-lost.mcap"
    host = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pmsm_hil.cli.main",
            "run",
            str(data / "long.yaml"),
            "--pace",
            "1",
            "--out",
            str(out),
            "--no-live",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60
        t_line = 0.0
        while time.monotonic() < deadline:
            m = re.match(r"t=\s*([0-9.]+)/", host.stdout.readline())
            if m and float(m.group(1)) >= 1.5:
                t_line = float(m.group(1))
                break
        children = emulator_children(host.pid)
        assert t_line and len(children) == 1
        os.kill(children[0], signal.SIGKILL)
        rest, err = host.communicate(timeout=30)
    finally:
        if host.poll() is None:
            host.kill()
    assert host.returncode == 3, err
    assert "dropped" in err and str(out) in err, err
    # the summary says an error ended the run (printed below it), not that the user stopped it
    assert "the run ended on an error (below)" in rest and "run interrupted" not in rest, rest
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None  # finalised: summary and index written
        ts = [m.log_time for _s, _c, m in reader.iter_messages(topics=["/pmsm/telemetry"])]
    offset_s = (ts[-1] - ts[0]) * 1e-9
    assert offset_s >= t_line - 0.1  # telemetry up to (at least) the last progress line


def test_the_run_after_a_killed_host_logs_only_its_own_session(data, tmp_path):
    """A host killed with -9 leaves its run's output in the port's buffer (the device streamed on
    until its heartbeat timeout): the next `run --port` on the same port logs none of it (before,
    the killed run's heartbeat-lost fault landed in the new log, exit 4, and its torn frame and
    sequence counted as frames lost on the link)."""
    from pmsm_hil.log.reader import read_log

    profile = load_profile(str(data / "long.yaml"))
    out = tmp_path / "next.mcap"
    with served_on_pty(profile) as (dev, server):
        run = [*_RUN, "--port", server.path]
        host = subprocess.Popen(
            [*run, str(data / "long.yaml"), "--out", str(tmp_path / "killed.mcap")],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            _wait_running(dev, profile)
            host.kill()
            host.wait(timeout=10)
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline and dev.state != STATE["idle"]:
                time.sleep(0.01)
            assert dev.state == STATE["idle"], "the killed host's motor was not brought to rest"
            r = subprocess.run(
                [*run, str(data / "short.yaml"), "--out", str(out)],
                capture_output=True,
                text=True,
                timeout=120,
            )
        finally:
            with contextlib.suppress(ProcessLookupError):
                host.kill()
    assert r.returncode == 0, r.stdout + r.stderr
    assert "all plateaus within bounds" in r.stdout and "lost frames" not in r.stdout
    log = read_log(out)
    kinds = [str(k) for k in log.topic("/pmsm/events")["kind"]]
    assert "heartbeat_lost" not in kinds and kinds.count("stopped") == 1
    link = log.topic("/host/link")
    assert int(link["seq_gaps"][-1]) == 0
    assert int(link["crc_errors"][-1]) + int(link["cobs_errors"][-1]) == 0
