"""CAN: layouts, paper-a over CAN, heartbeat over CAN, rejected-and-retried transfers, DBC, SPEC."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import cantools
import numpy as np
import pytest
from emu_helpers import socketcand_listener

from pmsm_hil.analysis.summary import summarize_log
from pmsm_hil.device import apply_can_rates, inprocess_can_link, open_can
from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import can_generated as cg
from pmsm_hil.protocol import codec
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.can_link import CanDecoder, encode_message
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, configure, run_profile
from pmsm_hil.transport.base import TransportError
from pmsm_hil.transport.can_bus import parse_spec

STATE = gen.ENUMS["state"]


def settings_for(profile, seed=1):
    return emulator_settings(
        profile.motor, profile.rig, seed=seed, baud=profile.link.baud, ts_s=profile.control.ts_s
    )


def run_can(profile_path, out, seed=1, link_kw=None, **opts):
    profile = load_profile(str(profile_path))
    apply_can_rates(profile)
    link = inprocess_can_link(settings_for(profile, seed), **(link_kw or {}))
    result = run_profile(profile, Session(link), out, RunOptions(seed=seed, **opts))
    return profile, result, link


def sample_fields(spec):
    out = {}
    for i, f in enumerate(spec.fields):
        if f.type == "f32":
            v = 1.5 + i
        elif f.scale is not None:
            v = round(3 * f.scale * (i + 1), 12)
        else:
            v = (i + 1) % 200
        out[f.name] = tuple([v] * f.count) if f.count > 1 else v
    return out


@pytest.mark.parametrize("spec", gen.MESSAGES, ids=lambda s: s.name)
def test_every_message_round_trips_through_can_frames(spec):
    fields = sample_fields(spec)
    frames = encode_message(spec.name, 77, **fields)
    assert all(len(d) <= 8 for _, d in frames)
    dec = CanDecoder(direction=spec.dir)
    (fr,) = dec.feed(frames)
    assert (fr.name, fr.seq) == (spec.name, 77)
    assert fr.fields == codec.decode_payload(spec.id, codec.encode_payload(spec.id, **fields))
    lay = cg.LAYOUTS[spec.id]
    assert [len(d) for _, d in frames] == list(lay.frame_octets)


@pytest.fixture(scope="module")
def paper_a_can(tmp_path_factory, request):
    out = tmp_path_factory.mktemp("can") / "paper-a-can.mcap"
    profile, result, link = run_can(request.config.rootpath / "profiles" / "paper-a.yaml", out)
    return profile, result, link, out


def test_paper_a_over_can_meets_the_serial_tracking_bounds(paper_a_can):
    profile, result, link, out = paper_a_can
    assert (result.state, result.stop_reason, result.faults) == ("done", "profile end", 0)
    summary = summarize_log(out)
    assert len(summary.segments) == 13
    for s in (s for s in summary.segments if s.setpoint_rpm != 0):
        assert abs(s.mean_error_rpm) <= s.band_rpm, (s.name, s.mean_error_rpm)
        assert abs(s.true_mean_error_rpm) <= s.band_rpm, (s.name, s.true_mean_error_rpm)
    steps = [s for s in summary.segments if s.recovery_s is not None]
    assert len(steps) == 6 and all(s.recovery_s <= 0.3 for s in steps)
    # the whole run streamed at the CAN rate, nothing lost, nothing dropped in the firmware
    tel = read_log(out).topic("/pmsm/telemetry")
    assert tel["t_s"][-1] >= profile.total_duration_s - 0.01
    assert np.allclose(np.diff(tel["t_s"]), 1.0 / profile.telemetry.fast_hz, atol=1e-9)
    assert link.decoder.seq_gaps == 0 and link.decoder.bad_frames == 0
    assert result.live.status["tx_dropped"] == 0
    assert len(read_log(out).topic("/pmsm/capture")["t_s"]) == 1024


def test_silent_host_over_can_stops_the_motor_within_the_heartbeat_time(data, tmp_path):
    profile, result, _ = run_can(data / "long.yaml", tmp_path / "hb.mcap", silent_after_s=1.5)
    assert result.stop_reason == "heartbeat lost"
    log = read_log(tmp_path / "hb.mcap")
    kinds = list(log.topic("/pmsm/events")["kind"])
    t_lost = log.topic("/pmsm/events")["t_s"][kinds.index("heartbeat_lost")]
    assert 1.5 < t_lost <= 1.5 + profile.control.heartbeat_timeout_s + 0.05
    tel = log.topic("/pmsm/telemetry")
    assert abs(tel["speed_rpm"][-1]) < 5.0 and tel["t_s"][-1] < t_lost + 1.0


@pytest.mark.parametrize("listener", [False, True], ids=["alone", "with-listener"])
def test_dropped_can_connection_stops_the_motor_within_the_heartbeat_time(data, listener):
    """With a listener on the bus too (it sends no heartbeats and reads nothing): it neither
    keeps the motor running nor holds the drive up once the host is gone."""
    from pmsm_hil.emulator.socketcand_server import SocketcandServer

    profile = load_profile(str(data / "long.yaml"))
    apply_can_rates(profile)
    dev = EmulatedDevice(settings_for(profile))
    server = SocketcandServer(dev)
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    idle = socketcand_listener(server.host, server.port) if listener else None
    try:
        link = open_can(parse_spec(server.spec))
        session = Session(link)
        session.hello()
        configure(session, profile)
        session.request("start")
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            session.poll(0.02)
            session.send("heartbeat", counter=0)
        assert dev.state == STATE["running"]
        link.close()  # the connection drops
        t_drop = time.monotonic()
        while dev.state == STATE["running"] and time.monotonic() - t_drop < 3.0:
            time.sleep(0.005)
        t_stop = time.monotonic() - t_drop
        assert dev.state in (STATE["stopping"], STATE["idle"])
        assert t_stop <= profile.control.heartbeat_timeout_s + 0.1, t_stop
        while dev.active and time.monotonic() - t_drop < 5.0:
            time.sleep(0.01)
        assert dev.state == STATE["idle"]  # brought to rest, PWM off
        if idle is not None:
            assert [c.is_node for c in server.clients] == [False]  # still there, listening
    finally:
        if idle is not None:
            idle.close()
        server.stop()
        thread.join(timeout=5)
        server.close()


class FirstTransferFault:
    """Spoils the first transfer on its way: a CRC error, a missing or a repeated data frame."""

    def __init__(self, kind: str, func: int, msg_id: int):
        self.kind, self.func, self.msg_id = kind, func, msg_id
        self.armed, self.done, self.headers = False, False, 0

    def __call__(self, frames):
        out = []
        for ident, data in frames:
            if ident >> 4 == self.func and data[0] == 0 and data[1] == self.msg_id:
                self.headers += 1
                self.armed = not self.done
            if self.armed and ident >> 4 == self.func and data[0] == 2:
                self.armed, self.done = False, True
                if self.kind == "crc":
                    out.append((ident, data[:3] + bytes([data[3] ^ 0x10]) + data[4:]))
                elif self.kind == "duplicate":
                    out += [(ident, data), (ident, data)]
                continue  # "missing": dropped
            out.append((ident, data))
        return out


@pytest.mark.parametrize("kind", ["crc", "missing", "duplicate"])
def test_corrupted_config_transfer_is_rejected_and_retried(data, kind):
    profile = load_profile(str(data / "short.yaml"))
    fault = FirstTransferFault(kind, cg.FUNC_TRANSFER_H2D, gen.ID_CONFIG_CTRL)
    link = inprocess_can_link(settings_for(profile), fault_h2d=fault)
    session = Session(link)
    session.hello()
    configure(session, profile)  # acknowledged in the end
    assert fault.done and fault.headers == 2  # the first attempt went unanswered: sent again


@pytest.mark.parametrize("kind", ["crc", "missing"])
def test_corrupted_capture_chunk_is_rejected_and_asked_for_again(data, tmp_path, kind):
    fault = FirstTransferFault(kind, cg.FUNC_TRANSFER_D2H, gen.ID_CAPTURE_CHUNK)
    _, result, link = run_can(
        data / "short.yaml", tmp_path / "cap.mcap", link_kw={"fault_d2h": fault}
    )
    assert fault.done
    assert link.decoder.crc_errors + link.decoder.order_errors + link.decoder.len_errors >= 1
    assert result.capture_samples == 1024
    cap = read_log(tmp_path / "cap.mcap").topic("/pmsm/capture")
    assert np.allclose(np.diff(cap["t_s"]), 50e-6, atol=1e-9)


def test_the_dbc_decodes_recorded_frames(data, root, tmp_path):
    db = cantools.database.load_file(str(root / "firmware" / "proto" / "pmsm_proto.dbc"))
    profile = load_profile(str(data / "short.yaml"))
    apply_can_rates(profile)
    link = inprocess_can_link(settings_for(profile))
    link.bus.recorded = []
    run_profile(
        profile, Session(link), tmp_path / "dbc.mcap", RunOptions(stop_after_s=0.3, capture=False)
    )
    rec = link.bus.recorded
    assert len(rec) > 1000
    by_name: dict[str, list] = {}
    for _t, ident, payload in rec:
        msg = db.get_message_by_frame_id(ident)
        # a transfer's last frame carries only what is left of the payload (its DLC below 8)
        short = msg.name.startswith("transfer_") and len(payload) < msg.length
        by_name.setdefault(msg.name, []).append(
            db.decode_message(ident, payload, allow_truncated=short)
        )
    # the DBC's telem_fast signals agree with the host's decoder, frame by frame
    frames = CanDecoder().feed([(i, d) for _t, i, d in rec])
    fast = [f.fields for f in frames if f.name == "telem_fast"]
    parts = [by_name[f"telem_fast_{k}"] for k in range(4)]
    assert len(fast) == len(parts[0]) > 100
    for k, f in enumerate(fast[:200]):
        dbc = {**parts[0][k], **parts[1][k], **parts[2][k], **parts[3][k]}
        for name, value in f.items():
            assert dbc[name] == pytest.approx(value, abs=1e-6), name
    assert {"status_0", "params_0", "event_0", "ack", "identify_0"} <= set(by_name)


@pytest.mark.parametrize(
    "text, expect",
    [
        ("socketcand:emu0@127.0.0.1:29536", ("socketcand", "emu0", None, None, "127.0.0.1", 29536)),
        ("socketcan:can0,bitrate=500000,node=3", ("socketcan", "can0", 500_000, 3, None, None)),
        ("slcan:/dev/ttyACM0", ("slcan", "/dev/ttyACM0", None, None, None, None)),
        ("emulator", ("emulator", "", None, None, None, None)),
        (None, ("emulator", "", None, None, None, None)),
    ],
)
def test_spec_parsing(text, expect):
    s = parse_spec(text)
    assert (s.interface, s.channel, s.bitrate, s.node, s.host, s.port) == expect
    if text and s.interface != "emulator":
        assert parse_spec(s.text()) == s


@pytest.mark.parametrize(
    "text, words",
    [
        ("can0", "expected INTERFACE:CHANNEL"),
        ("bogus:can0", "unknown interface"),
        ("socketcan:can0,node=16", "node 16"),
        ("socketcan:can0,bitrate=2000000", "bitrate"),
        ("socketcand:emu0", "CHANNEL@HOST:PORT"),
        ("socketcan:can0,foo", "key=value"),
    ],
)
def test_bad_spec_is_refused_clearly(text, words):
    with pytest.raises(TransportError, match=words):
        parse_spec(text)


def test_unreachable_or_missing_interface_is_a_clear_error():
    with pytest.raises(TransportError, match="cannot connect"):
        open_can(parse_spec("socketcand:emu0@127.0.0.1:1"))
    with pytest.raises(TransportError, match="CAN"):
        open_can(parse_spec("socketcan:nosuchcan7"))


def test_the_telemetry_rates_fit_the_bit_rate_that_spec_gives(data):
    """`--can SPEC,bitrate=500000`: the fast-frame rate is fitted to 500 kbit/s. It was fitted to
    the profile's 1 Mbit/s, and the device dropped a third of the telemetry."""
    from pmsm_hil.device import DeviceSpec, open_can_for_run
    from pmsm_hil.protocol.can_link import can_fast_hz_max

    profile = load_profile(str(data / "short.yaml"))  # no link.can: the rate is fitted
    tel = profile.telemetry
    others = {"params": tel.params_hz, "status": tel.status_hz, "sim_truth": tel.truth_hz}
    link = open_can_for_run(DeviceSpec(can="virtual:fit500,bitrate=500000,node=3"), profile)
    link.close()
    assert (profile.link.can.bitrate, profile.link.can.node) == (500_000, 3)
    fit = can_fast_hz_max(others, profile.control.ts_s, 500_000)
    assert profile.telemetry.fast_hz == fit < can_fast_hz_max(others, profile.control.ts_s, 1e6)
    # the emulator with a bit rate is still the emulator: its run keeps its seed
    assert not DeviceSpec(can="emulator,bitrate=500000").is_rig
    assert DeviceSpec(can="virtual:ch0,bitrate=500000").is_rig


@pytest.mark.parametrize(
    "command, link_args, words",
    [
        ("run", ["--port", "/dev/ttyUSB0", "--can"], "give one link"),
        ("run", ["--port", "/dev/ttyUSB0", "--can", "socketcan:can0"], "give one link"),
        ("run", ["--can", "--baud", "115200"], "bitrate=N"),
        ("commission", ["--port", "/dev/ttyUSB0", "--can"], "give one link"),
    ],
)
def test_a_serial_port_and_can_together_are_refused_before_anything_runs(
    data, tmp_path, command, link_args, words
):
    """--port and --can name two links: the run used to go to the emulator on CAN, the rig's port
    never opened (and --baud over CAN was ignored)."""
    out = tmp_path / ("x.mcap" if command == "run" else "m.yaml")
    target = [str(data / "short.yaml")] if command == "run" else []
    r = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", command, *target, *link_args, "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    assert words in r.stderr and "Traceback" not in r.stderr
    assert not out.exists() and not (tmp_path / "runs").exists()


def test_cli_emulate_can_prints_a_spec_that_run_connects_to(data, tmp_path):
    emu = subprocess.Popen(
        [sys.executable, "-m", "pmsm_hil.emulator", "--can"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = emu.stdout.readline().strip()
        assert line.startswith("can: socketcand:emu0@127.0.0.1:")
        spec = line.split(" ", 1)[1]
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "pmsm_hil.cli.main",
                "run",
                str(data / "short.yaml"),
                "--can",
                spec,
                "--no-live",
                "-o",
                str(tmp_path / "c.mcap"),
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
        assert "all plateaus within bounds" in r.stdout
        assert "CAN socketcand" in read_log(tmp_path / "c.mcap").metadata["run"]["transport"]
    finally:
        emu.terminate()
        emu.wait(timeout=5)


def test_a_second_host_on_the_bus_cannot_take_over_a_running_motor(data, tmp_path):
    """The endpoint is a bus (docs/can.md): a second `pmsm-hil run` joins it while the first's
    motor runs, and the drive refuses its configuration (busy); the first runs to its end."""
    # the emulator in real time and 9 s of profile (long.yaml's 601 s took 86 s over CAN)
    held = tmp_path / "held.yaml"
    held.write_text(
        (data / "long.yaml")
        .read_text()
        .replace("../../profiles", str(data.parents[1] / "profiles"))
        .replace("duration_s: 600.0", "duration_s: 8.0")
    )
    emu = subprocess.Popen(
        [sys.executable, "-m", "pmsm_hil.emulator", "--can", "--pace", "1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        spec = emu.stdout.readline().strip().split(" ", 1)[1]
        first = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "pmsm_hil.cli.main",
                "run",
                str(held),
                "--can",
                spec,
                "--no-live",
                "-o",
                str(tmp_path / "first.mcap"),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not first.stdout.readline().startswith("t="):
            pass
        second = subprocess.run(
            [
                sys.executable,
                "-m",
                "pmsm_hil.cli.main",
                "run",
                str(data / "short.yaml"),
                "--can",
                spec,
                "--no-live",
                "-o",
                str(tmp_path / "second.mcap"),
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert second.returncode == 3, second.stdout[-2000:] + second.stderr[-2000:]
        assert "device refused config_motor (busy)" in second.stderr
        assert "Traceback" not in second.stderr
        out, err = first.communicate(timeout=180)
        assert first.returncode == 0, err[-2000:]  # the first session ran to its end undisturbed
        assert "all plateaus within bounds" in out
    finally:
        emu.terminate()
        emu.communicate(timeout=10)
