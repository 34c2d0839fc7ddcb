"""CAN as other tools and other nodes see it: frames of another node on the drive's identifiers,
the DBC's value tables, the DBC installed with the package, the emulator's endpoint as a bus that
tools listen on beside a run (docs/can.md)."""

from __future__ import annotations

import json
import os
import re
import select
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import cantools
import pytest
from emu_helpers import DEVICE_TOPICS, raw_messages, socketcand_listener

from pmsm_hil.analysis.summary import summarize_log
from pmsm_hil.device import DeviceSpec, apply_can_rates, inprocess_can_link, open_device
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.emulator.socketcand_client import LISTENER_SETTLE_S
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import dbc_path
from pmsm_hil.protocol.can_link import CanDecoder
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile


def test_frames_the_drive_rejects_are_in_the_run_summary(data, tmp_path):
    """Another node sends on one of the drive's identifiers (0x181, a CANopen TPDO1 of node 1, is
    sim_plant's first frame for node 1, 8 octets instead of 7): the firmware rejects each and
    counts it in rx_bad, and the run summary says so, as docs/faults.md promises (it read only
    tx_dropped of /pmsm/status and never said it)."""
    profile = load_profile(str(data / "short.yaml"))
    apply_can_rates(profile)
    settings = emulator_settings(
        profile.motor, profile.rig, seed=1, baud=profile.link.baud, ts_s=profile.control.ts_s
    )
    foreign = []

    def other_node(frames):
        if any(ident == 0x031 for ident, _ in frames):  # beside each heartbeat
            foreign.append(1)
            return [*frames, (0x181, bytes(range(8)))]
        return frames

    def toward_host(frames):  # a CANopen heartbeat of node 1 beside the drive's frames
        return [*frames, (0x701, bytes([5]))] if frames else frames

    link = inprocess_can_link(settings, fault_h2d=other_node, fault_d2h=toward_host)
    out = tmp_path / "shared.mcap"
    run_profile(profile, Session(link), out, RunOptions(capture=False))  # the whole profile
    assert len(foreign) >= 5
    summary = summarize_log(out)
    problems = summary.problems
    assert any("the device rejected" in p for p in problems), problems
    # the host's count of frames it does not know is said too, and the verdict names what is
    # missing rather than calling a whole file damaged
    assert any("frames of an identifier it does not know" in p for p in problems), problems
    from pmsm_hil.analysis.summary_text import verdict_text

    verdict = verdict_text(summary)
    assert "the file is damaged" not in verdict
    assert "INCOMPLETE[/] (the record is not whole: the device rejected" in verdict, verdict
    assert verdict.endswith("): the segments are within bounds"), verdict


def test_the_dbc_names_enum_values_as_the_log_does(root):
    """A CAN analyser shows `running`, `nominal`, `config_ctrl`, not 1, 0, 3: every field whose
    yaml comment names an enum has its value table, and a transfer header's msg_id too."""
    from pmsm_hil.protocol import can_generated as cg
    from pmsm_hil.protocol import generated as gen
    from pmsm_hil.protocol.can_link import encode_message

    db = cantools.database.load_file(str(root / "firmware" / "proto" / "pmsm_proto.dbc"))
    state = gen.ENUMS["state"]
    est = gen.ENUMS["estimator"]
    ((ident, data), *_) = encode_message(
        "status",
        5,
        tick=1,
        state=state["running"],
        segment=0,
        faults=0,
        v_dc_v=540.0,
        tx_dropped=0,
        rx_bad=0,
        rx_frames=0,
        hb_age_ms=0,
        capture_count=0,
    )
    assert str(db.decode_message(ident, data)["state"]) == "running"
    ((ident, data), *_) = encode_message(
        "params",
        6,
        tick=1,
        estimator=est["rls"],
        flags=0,
        l_d_h=0.005,
        l_q_h=0.012,
        psi_f_wb=0.18,
        r_s_ohm=0.9,
    )
    assert str(db.decode_message(ident, data)["estimator"]) == "rls"
    head = bytes((0, gen.BY_NAME["config_ctrl"].id, 1, 100, 0, 0))
    msg = db.get_message_by_frame_id(cg.FUNC_TRANSFER_H2D << cg.NODE_BITS | cg.NODE)
    assert str(msg.decode(head, allow_truncated=True)["msg_id"]) == "config_ctrl"
    # bit masks keep their raw value (a value table would name only single bits)
    assert db.get_message_by_name("status_1").get_signal_by_name("faults").choices is None


def test_the_dbc_is_installed_and_profiles_prints_its_path(tmp_path, root, built_package):
    """docs/can.md named firmware/proto/pmsm_proto.dbc, which `pip install` left behind: a user
    of an installed pmsm-hil had no DBC. It is package data now, and `pmsm-hil profiles` says
    where."""
    import subprocess
    import sys

    from pmsm_hil.protocol import dbc_path

    lib = built_package
    installed = lib / "pmsm_hil" / "proto" / "pmsm_proto.dbc"
    assert installed.read_bytes() == (root / "firmware" / "proto" / "pmsm_proto.dbc").read_bytes()
    assert dbc_path().is_file()
    r = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", "profiles"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if "CAN database" in x)
    assert line.endswith(str(dbc_path())), line


def test_the_dbcs_integer_signals_carry_the_range_of_their_wire_type():
    """An analyser's [min|max] is the physical range the wire type carries (it was [0|0] for
    every signal): an i16 speed at 0.1 r/min spans -3276.8 .. 3276.7 r/min."""
    from pmsm_hil.protocol import dbc_path

    db = cantools.database.load_file(str(dbc_path()))
    speed = db.get_message_by_name("telem_fast_1").get_signal_by_name("speed_rpm")
    assert (speed.minimum, speed.maximum) == (-3276.8, 3276.7)
    # (a transfer's `data` is 7 raw payload octets, not a quantity: no range)
    ints = [s for m in db.messages for s in m.signals if not s.is_float and s.name != "data"]
    assert ints and all(s.minimum is not None and s.maximum > s.minimum for s in ints)
    floats = [s for m in db.messages for s in m.signals if s.is_float]
    assert floats and all(s.minimum is None for s in floats)  # an f32 carries no fixed range


# ---------------------------------------------------------------- the emulator's endpoint is a bus
SHORT = Path(__file__).resolve().parent / "data" / "short.yaml"
MARKER_ID = 0x70F  # a CANopen heartbeat of node 15: another node, which the drive (node 1) ignores

# a listener as an engineer runs one: python-can's socketcand client in a process of its own; it
# stops at the marker frame (sent once the run is over) and writes what it got as JSON
LISTENER = """
import json, logging, sys
import can
logging.getLogger("can").setLevel(logging.ERROR)
host, port, marker, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3], 16), sys.argv[4]
bus = can.Bus(interface="socketcand", channel="emu0", host=host, port=port)
print("listening", flush=True)
frames, seen = [], False
try:
    while not seen:
        msg = bus.recv(120.0)
        if msg is None:
            break
        seen = msg.arbitration_id == marker
        if not seen:
            frames.append([msg.arbitration_id, msg.data.hex()])
finally:
    bus.shutdown()
with open(out, "w") as f:
    json.dump({"marker_seen": seen, "frames": frames}, f)
"""


class CanEmulator:
    """`python -m pmsm_hil.emulator --can ARGS` (seed 1): its endpoint, its stderr."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "pmsm_hil.emulator", "--can", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        line = self.proc.stdout.readline().strip()
        assert line.startswith("can: socketcand:emu0@"), line
        self.spec = line.split(" ", 1)[1]
        host, port = self.spec.split("@", 1)[1].rsplit(":", 1)
        self.host, self.port = host, int(port)
        self._err = ""

    def wait_for_stderr(self, pattern: str, timeout_s: float = 60.0) -> re.Match:
        """The first match of `pattern` in the running emulator's stderr (waits for it)."""
        fd = self.proc.stderr.fileno()
        deadline = time.monotonic() + timeout_s
        while (m := re.search(pattern, self._err)) is None:
            left = deadline - time.monotonic()
            assert left > 0, f"the emulator did not say {pattern!r}; its stderr: {self._err}"
            if select.select([fd], [], [], left)[0]:
                self._err += os.read(fd, 65536).decode(errors="replace")
        return m

    def stop(self) -> str:
        """Stops it; all it wrote on stderr."""
        if self.proc.poll() is None:
            self.proc.terminate()
        _, err = self.proc.communicate(timeout=10)
        self._err += err
        return self._err


def run_short(spec: str, out: Path):
    """short.yaml over CAN through `spec`, as `pmsm-hil run --can SPEC` runs it."""
    from pmsm_hil.transport import quiet_python_can

    quiet_python_can()
    profile = load_profile(str(SHORT))
    link = open_device(DeviceSpec(can=spec), profile)
    try:
        return run_profile(profile, Session(link), out, RunOptions(seed=1))
    finally:
        link.close()


def device_record(path: Path) -> tuple[list, list]:
    """What the log holds from the device: its messages as recorded, and its events (the host's
    own events name the endpoint, whose port differs from run to run)."""
    ev = read_log(path).topic("/pmsm/events")
    events = [
        row
        for row in zip(ev["t_s"], ev["kind"], ev["code"], ev["arg"], ev["text"], strict=True)
        if row[1] != "host"
    ]
    return raw_messages(path, tuple(t for t in DEVICE_TOPICS if t != "/pmsm/events")), events


def send_marker(host: str, port: int) -> None:
    """Another node's frame onto the bus: every listener gets it after all that came before."""
    node = socketcand_listener(host, port)
    node.sendall(f"< send {MARKER_ID:03X} 1 5 >".encode("ascii"))
    node.close()


@pytest.fixture(scope="module")
def run_alone(tmp_path_factory):
    """short.yaml over CAN with nobody else on the bus: (result, log)."""
    emu = CanEmulator()
    try:
        out = tmp_path_factory.mktemp("alone") / "alone.mcap"
        result = run_short(emu.spec, out)
    finally:
        emu.stop()
    assert (result.state, result.stop_reason, result.faults) == ("done", "profile end", 0)
    return result, out


def test_python_can_listens_beside_a_run_and_the_run_is_the_same(run_alone, tmp_path):
    """python-can's socketcand client opens the emulator's channel while `pmsm-hil run` drives it
    (it was refused `busy`): it gets the drive's frames, whose telemetry is the run's own, and
    the host's heartbeats; the run's log is the one it makes alone. The emulator runs in real
    time (`--pace 1`, as a rig), which a listener keeps up with; what it could not take would be
    dropped and said, and is allowed for."""
    emu = CanEmulator("--pace", "1")
    script = tmp_path / "listener.py"
    script.write_text(LISTENER)
    got = tmp_path / "bus.json"
    listener = subprocess.Popen(
        [sys.executable, str(script), emu.host, str(emu.port), f"{MARKER_ID:X}", str(got)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert listener.stdout.readline().strip() == "listening", listener.communicate()[1]
        # its frames start LISTENER_SETTLE_S after its rawmode reply (python-can's handshake)
        time.sleep(2 * LISTENER_SETTLE_S)
        result = run_short(emu.spec, tmp_path / "beside.mcap")
        send_marker(emu.host, emu.port)
        _, listener_err = listener.communicate(timeout=120)
        assert listener.returncode == 0, listener_err[-3000:]
    finally:
        if listener.poll() is None:
            listener.kill()
            listener.wait(timeout=10)
        emu_err = emu.stop()
    alone, alone_log = run_alone
    assert (result.state, result.stop_reason, result.faults) == ("done", "profile end", 0)
    assert (result.live.seq_gaps, result.capture_samples) == (0, alone.capture_samples)
    assert device_record(tmp_path / "beside.mcap") == device_record(alone_log)

    bus = json.loads(got.read_text())
    assert bus["marker_seen"]
    frames = [(ident, bytes.fromhex(data)) for ident, data in bus["frames"]]
    dropped = sum(int(n) for n in re.findall(r"left: (\d+) frames dropped", emu_err))
    # every frame is one of the installed DBC's; the drive's state and the host's heartbeat by name
    db = cantools.database.load_file(str(dbc_path()))
    names = [db.get_message_by_frame_id(ident).name for ident, _ in frames]
    states = {
        str(db.decode_message(i, d)["state"])
        for (i, d), n in zip(frames, names, strict=True)
        if n == "status_0"
    }
    assert "running" in states
    assert names.count("heartbeat") >= 3  # the host's frames reach the other clients too
    # the drive's telemetry, reassembled with its end-to-end check: the run's, message by message
    tel = read_log(alone_log).topic("/pmsm/telemetry")
    ts_s = load_profile(str(SHORT)).control.ts_s
    row = {round(t / ts_s): k for k, t in enumerate(tel["t_s"])}
    fast = [f.fields for f in CanDecoder().feed(frames) if f.name == "telem_fast"]
    # a frame dropped for it costs at most one message
    assert len(tel["t_s"]) - dropped <= len(fast) <= len(tel["t_s"]), emu_err
    for f in fast:
        k = row[f["tick"]]
        assert {n: v for n, v in f.items() if n in tel} == pytest.approx(
            {n: tel[n][k] for n in f if n in tel}, abs=1e-9
        )


def test_a_listener_that_never_reads_does_not_hold_up_the_run(run_alone, tmp_path):
    """A client that opens the channel and then reads nothing (a small receive buffer too): the
    drive does not wait for it. The run is the one it makes alone; the listener is not cut off,
    what it was sent is whole frames, and the frames dropped for it are said when it leaves."""
    emu = CanEmulator()
    try:
        idle = socketcand_listener(emu.host, emu.port, rcvbuf_octets=4096)
        result = run_short(emu.spec, tmp_path / "idle.mcap")
        assert (result.state, result.stop_reason, result.faults) == ("done", "profile end", 0)
        # still connected: what waits for it is read up to "nothing more now" at a frame's end
        # (the server may be halfway through sending one), and no end of file comes
        idle.setblocking(False)
        text = b""
        while True:
            try:
                part = idle.recv(1 << 16)
            except BlockingIOError:
                if text.endswith(b">"):
                    break
                assert select.select([idle], [], [], 30.0)[0], "the rest of a frame did not come"
                continue
            assert part, "the endpoint closed the listener's connection"
            text += part
        idle.close()
        dropped = int(emu.wait_for_stderr(r"CAN listener \S+ left: (\d+) frames dropped").group(1))
    finally:
        emu.stop()
    assert device_record(tmp_path / "idle.mcap") == device_record(run_alone[1])
    frames = re.findall(rb"<[^<>]*>", text)
    assert b"".join(frames) == text and len(frames) > 100
    assert all(re.fullmatch(rb"< frame [0-9A-F]{3} \d+\.\d{6} [0-9A-F]* >", f) for f in frames)
    # what it got and what it was told it lost: at least the run's telemetry, 4 frames a message
    telemetry_frames = 4 * len(read_log(run_alone[1]).topic("/pmsm/telemetry")["t_s"])
    assert dropped > 0 and len(frames) + dropped >= telemetry_frames


def test_a_clients_frame_goes_to_the_device_and_the_other_clients_not_back(data):
    """On a bus the other nodes see a frame, its sender does not get it back: a hello from one
    client reaches the drive (it answers identify to all) and the other client; a connection
    that never opened a channel (a probe) gets no frames."""
    from pmsm_hil.emulator.fwlib import EmulatedDevice
    from pmsm_hil.emulator.socketcand_server import SocketcandServer
    from pmsm_hil.protocol import generated as gen
    from pmsm_hil.protocol.can_link import encode_message

    profile = load_profile(str(data / "short.yaml"))
    apply_can_rates(profile)
    dev = EmulatedDevice(
        emulator_settings(
            profile.motor, profile.rig, seed=1, baud=profile.link.baud, ts_s=profile.control.ts_s
        )
    )
    server = SocketcandServer(dev)
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    try:
        probe = socket.create_connection((server.host, server.port), timeout=30)
        node = socketcand_listener(server.host, server.port)
        other = socketcand_listener(server.host, server.port)
        time.sleep(2 * LISTENER_SETTLE_S)  # `other` gets frames from now on
        ((ident, payload),) = encode_message("hello", 3, host_proto_version=gen.PROTOCOL_VERSION)
        octets = " ".join(f"{b:02X}" for b in payload)
        node.sendall(f"< send {ident:03X} {len(payload):X} {octets} >".encode("ascii"))

        def until_identify(sock: socket.socket) -> str:
            text = ""
            while "< frame 0B1 " not in text:  # identify's last frame
                part = sock.recv(4096)
                assert part, text
                text += part.decode("ascii")
            return text

        seen_by_node, seen_by_other = until_identify(node), until_identify(other)
        assert "< frame 081 " not in seen_by_node  # its own frame is not echoed
        assert seen_by_other.index("< frame 081 ") < seen_by_other.index("< frame 091 ")
        echoed = rf"< frame 081 \d+\.\d{{6}} {payload.hex().upper()} >"
        assert re.search(echoed, seen_by_other), seen_by_other[:200]
        assert probe.recv(64) == b"< hi >"
        probe.setblocking(False)
        with pytest.raises(BlockingIOError):
            probe.recv(64)  # nothing after its greeting
        assert server.frames_in == 1
        for sock in (probe, node, other):
            sock.close()
    finally:
        server.stop()
        thread.join(timeout=5)
        server.close()
