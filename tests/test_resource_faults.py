"""Resource faults during a run, end to end: the log's disk fills up (a file size limit on the host
process: its writes fail as on a full disk) and the link is noisy. Each stops the motor safely
(seen from the emulator's own state), leaves a readable log and ends with a clear message."""

from __future__ import annotations

import resource
import subprocess
import sys
import time

import pytest
from emu_helpers import served_on_pty

from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import generated as gen

STATE = gen.ENUMS["state"]
LIMIT_OCTETS = 400_000  # about 3 s of long.yaml's log


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_OCTETS, LIMIT_OCTETS))


def test_a_full_disk_mid_run_stops_the_motor_and_leaves_a_readable_log(data, tmp_path):
    profile = load_profile(str(data / "long.yaml"))  # 600 s: only the fault ends it
    out = tmp_path / "full.mcap"
    with served_on_pty(profile) as (dev, server):
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "pmsm_hil.cli.main",
                "run",
                str(data / "long.yaml"),
                "--port",
                server.path,
                "--out",
                str(out),
                "--no-live",
            ],
            preexec_fn=_limit_file_size,
            capture_output=True,
            text=True,
            timeout=120,
        )
        t_exit = time.monotonic()
        assert r.returncode == 3, r.stderr
        assert "Traceback" not in r.stderr
        assert f"cannot write the log {out}: File too large" in r.stderr
        assert "the motor was stopped (device idle, host stop)" in r.stderr
        assert "pmsm-hil log recover" in r.stderr
        # the emulator's own view: the motor came to rest under the host's stop command
        while dev.active and time.monotonic() - t_exit < 10:
            time.sleep(0.01)
        assert dev.state == STATE["idle"]
    assert out.stat().st_size <= LIMIT_OCTETS
    log = read_log(out)  # everything up to the last chunk that fit
    assert not log.finalised
    tel = log.topic("/pmsm/telemetry")
    assert len(tel["t_s"]) > 1000 and tel["t_s"][-1] > 1.0
    fixed = tmp_path / "fixed.mcap"
    rec = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", "log", "recover", str(out), "-o", str(fixed)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert rec.returncode == 0 and read_log(fixed).finalised, rec.stderr


@pytest.mark.parametrize("when", ["start", "close"])
def test_a_write_error_is_a_log_write_error_and_the_file_stays_readable(tmp_path, when):
    """The writer itself: an I/O error while a chunk (or the summary) goes out raises
    LogWriteError, saying what the file holds; nothing more is written, close() is quiet."""
    import errno

    from pmsm_hil.log.writer import LogWriteError, LogWriter

    path = tmp_path / "enospc.mcap"
    w = LogWriter(path, chunk_span_s=0.1)
    for k in range(10):  # chunks of 0.1 s: 4 on disk, the 5th (0.40, 0.45) open
        w.write("/pmsm/events", 0.05 * k, {"kind": "host", "text": f"{k}"})

    class Full:  # the stream under the MCAP records: the disk is full from here on
        def __init__(self, f):
            self.f = f

        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

        def __getattr__(self, name):
            return getattr(self.f, name)

    w._w._f = Full(w._f)
    with pytest.raises(LogWriteError) as e:
        if when == "start":
            w.write("/pmsm/events", 1.0, {"kind": "host", "text": "x"})
        else:
            w.close()
    assert e.value.errno == errno.ENOSPC
    assert "No space left on device" in e.value.strerror
    assert e.value.disk_t_s == pytest.approx(0.35)  # the chunks before: 0 .. 0.35 s
    assert "up to t = 0.350 s" in e.value.strerror
    with pytest.raises(LogWriteError):
        w.write("/pmsm/events", 2.0, {"kind": "host", "text": "y"})
    w.close()  # quiet now
    assert read_log(path).counts["/pmsm/events"] == 8


def _noisy_run(data, tmp_path, flip_ppm, drop_ppm, seed, after_s=0.0):
    """short.yaml in process, noise both ways (from device time after_s on); returns (result or
    error, device, accepted-not-sent, host decoder, log path)."""
    from pmsm_hil.emulator.link_noise import LinkNoise
    from pmsm_hil.protocol import codec
    from pmsm_hil.protocol.link import SerialLink
    from pmsm_hil.protocol.session import Session
    from pmsm_hil.runner import RunOptions, run_profile
    from pmsm_hil.transport.inproc import InProcessTransport

    profile = load_profile(str(data / "short.yaml"))
    settings = emulator_settings(
        profile.motor, profile.rig, seed=1, baud=profile.link.baud, ts_s=profile.control.ts_s
    )
    dev = EmulatedDevice(settings)
    clean, sent = codec.FrameDecoder(), set()
    noisy = lambda: dev.isr_count * profile.control.ts_s >= after_s  # noqa: E731

    noise_d2h, noise_h2d = (
        LinkNoise(flip_ppm, drop_ppm, seed),
        LinkNoise(flip_ppm, drop_ppm, seed + 1),
    )

    def d2h(b):
        sent.update((f.msg_id, f.seq, repr(f.fields)) for f in clean.feed(b))
        return noise_d2h(b) if noisy() else b

    def h2d(b):
        return noise_h2d(b) if noisy() else b

    link = SerialLink(InProcessTransport(settings, device=dev, noise_d2h=d2h, noise_h2d=h2d))
    accepted = []
    feed = link.decoder.feed

    def host_feed(b):
        frames = feed(b)
        accepted.extend(frames)
        return frames

    link.decoder.feed = host_feed
    out = tmp_path / f"noise-{flip_ppm}-{drop_ppm}-{seed}.mcap"
    try:
        result = run_profile(profile, Session(link), out, RunOptions(seed=1))
    except Exception as e:
        result = e
    limit = int((profile.control.heartbeat_timeout_s + 1.0) / profile.control.ts_s)
    ran = 0
    while dev.active and ran < limit:  # the host is gone: the device runs on alone
        dev.run(400)
        ran += 400
    bad = [f for f in accepted if (f.msg_id, f.seq, repr(f.fields)) not in sent]
    return result, dev, bad, link.decoder, out


@pytest.mark.parametrize(
    "flip_ppm, drop_ppm, seed", [(1000, 0, 21), (0, 1000, 22), (20000, 5000, 23), (50000, 0, 24)]
)
def test_a_noisy_serial_link_lets_nothing_corrupt_through_and_ends_safely(
    data, tmp_path, flip_ppm, drop_ppm, seed
):
    result, dev, bad, dec, out = _noisy_run(data, tmp_path, flip_ppm, drop_ppm, seed)
    assert bad == []  # no message accepted that the device had not sent
    assert not dev.active  # the motor at rest, whatever ended the run
    if isinstance(result, Exception):  # refused before the start: the motor never ran
        assert "did not acknowledge" in str(result) and dev.state == STATE["idle"]
        return
    assert read_log(out).finalised
    if flip_ppm + drop_ppm <= 1000:  # a mildly noisy line: the run completes, losses counted
        assert (result.state, result.stop_reason) == ("done", "profile end")
        assert dec.crc_errors + dec.cobs_errors + dec.len_errors > 0 and dec.seq_gaps > 0
    else:
        assert result.state in ("done", "idle", "fault") and result.stop_reason


@pytest.mark.parametrize("flip_ppm, drop_ppm, seed", [(50000, 0, 31), (20000, 20000, 32)])
def test_heavy_noise_in_the_middle_of_a_run_stops_the_motor_safely(
    data, tmp_path, flip_ppm, drop_ppm, seed
):
    """The line turns bad 1 s into the run: whatever ends it (the device's heartbeat timeout, the
    host's silence check), the motor comes to rest, nothing corrupt is accepted, the log is whole."""
    result, dev, bad, dec, out = _noisy_run(data, tmp_path, flip_ppm, drop_ppm, seed, after_s=1.0)
    assert bad == [] and not dev.active
    assert not isinstance(result, Exception), result
    assert result.stop_reason or result.error
    assert dec.crc_errors + dec.cobs_errors + dec.len_errors > 50
    log = read_log(out)
    assert log.finalised and log.topic("/pmsm/telemetry")["t_s"][-1] > 1.0


def test_burst_frame_loss_on_can_mid_run_lets_nothing_corrupt_through(data, tmp_path):
    """CAN at 20 % of the frames lost in bursts of 1..8, both ways, from 1 s into the run: every
    message the host accepts is one the device sent, the motor comes to rest, the log is whole."""
    import random

    from pmsm_hil.device import apply_can_rates, inprocess_can_link
    from pmsm_hil.protocol.can_link import CanDecoder
    from pmsm_hil.protocol.session import Session
    from pmsm_hil.runner import RunOptions, run_profile

    profile = load_profile(str(data / "short.yaml"))
    apply_can_rates(profile)
    settings = emulator_settings(
        profile.motor, profile.rig, seed=1, baud=profile.link.baud, ts_s=profile.control.ts_s
    )
    dev = EmulatedDevice(settings)
    noisy = lambda: dev.isr_count * profile.control.ts_s >= 1.0  # noqa: E731

    def bursts(seed):
        rng, left = random.Random(seed), [0]

        def hook(frames):
            out = []
            for f in frames:
                if noisy() and not left[0] and rng.random() < 0.2 / (4.5 * 0.8):
                    left[0] = rng.randint(1, 8)
                if left[0]:
                    left[0] -= 1
                    continue
                out.append(f)
            return out

        return hook

    clean, sent, lose_d2h = CanDecoder(), set(), bursts(41)

    def d2h(frames):
        sent.update((f.msg_id, f.seq, repr(f.fields)) for f in clean.feed(frames))
        return lose_d2h(frames)

    link = inprocess_can_link(settings, device=dev, fault_d2h=d2h, fault_h2d=bursts(42))
    accepted, feed = [], link.decoder.feed

    def host_feed(frames):
        got = feed(frames)
        accepted.extend(got)
        return got

    link.decoder.feed = host_feed
    out = tmp_path / "can-bursts.mcap"
    result = run_profile(profile, Session(link), out, RunOptions(seed=1))
    for _ in range(40):  # the host is gone: the device runs on alone
        dev.run(400)
    assert [f for f in accepted if (f.msg_id, f.seq, repr(f.fields)) not in sent] == []
    assert link.decoder.crc_errors + link.decoder.order_errors > 20  # losses seen and counted
    assert not dev.active and (result.stop_reason or result.error)
    assert read_log(out).finalised
