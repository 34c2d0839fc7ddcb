"""Helpers shared by the tests that run profiles on the in-process emulator, and a bare client of
the emulator's CAN endpoint (socketcand)."""

from __future__ import annotations

import contextlib
import os
import socket
import threading

from mcap.reader import make_reader

from pmsm_hil.device import DeviceSpec, open_device
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile

DEVICE_TOPICS = ("/pmsm/telemetry", "/pmsm/params", "/pmsm/events", "/pmsm/capture", "/sim/truth")


@contextlib.contextmanager
def served_on_pty(profile):
    """The emulator for ``profile`` served on a pty in this process (its state readable here):
    (device, server); stopped and closed on the way out."""
    from pmsm_hil.emulator.fwlib import EmulatedDevice
    from pmsm_hil.emulator.server import PtyServer
    from pmsm_hil.emulator.settings import emulator_settings

    settings = emulator_settings(
        profile.motor, profile.rig, seed=1, baud=profile.link.baud, ts_s=profile.control.ts_s
    )
    dev = EmulatedDevice(settings)
    server = PtyServer(dev)
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    try:
        yield dev, server
    finally:
        server.stop()
        thread.join(timeout=5)
        server.close()


def run_inproc(profile_path, out, seed=1, rig=None, **opts):
    profile = load_profile(str(profile_path), rig_override=rig)
    link = open_device(DeviceSpec(in_process=True, seed=seed), profile)
    result = run_profile(profile, Session(link), out, RunOptions(seed=seed, **opts))
    return profile, result


def raw_messages(path, topics=DEVICE_TOPICS):
    """(topic, device time in ns, payload) of every message: log_time is wall-clock (the run's
    start plus device time), so the run's start, kept in the metadata, is taken off."""
    out = []
    with open(path, "rb") as f:
        reader = make_reader(f)
        offset = 0
        for m in reader.iter_metadata():
            if m.name == "log":
                offset = int(m.metadata.get("log_time_offset_ns", "0"))
        for _schema, channel, msg in reader.iter_messages(topics=list(topics)):
            out.append((channel.topic, msg.log_time - offset, bytes(msg.data)))
    return out


def emulator_children(pid: int) -> list[int]:
    """Emulator processes started by the host `pid` (they run in sessions of their own)."""
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
            if ppid == pid:
                out.append(int(d))
    return out


def socketcand_listener(
    host: str, port: int, channel: str = "emu0", rcvbuf_octets: int | None = None
) -> socket.socket:
    """A client of a socketcand endpoint with its channel open in raw mode (docs/can.md), as a
    bare socket that reads nothing more: the caller reads the frames, or never does. Each reply
    of the handshake is checked. ``rcvbuf_octets`` shrinks its receive buffer (a slow reader)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    if rcvbuf_octets is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf_octets)
    sock.settimeout(30.0)
    sock.connect((host, port))
    for send, want in (
        (None, b"< hi >"),
        (f"< open {channel} >", b"< ok >"),
        ("< rawmode >", b"< ok >"),
    ):
        if send is not None:
            sock.sendall(send.encode("ascii"))
        got = b""
        while len(got) < len(want):
            part = sock.recv(len(want) - len(got))
            assert part, f"the endpoint closed the connection; it had sent {got!r}"
            got += part
        assert got == want, (send, got)
    return sock
