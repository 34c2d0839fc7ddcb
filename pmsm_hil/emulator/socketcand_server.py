"""The emulator on a CAN endpoint: the socketcand protocol (raw mode) on 127.0.0.1, which python-can's
`socketcand` interface speaks (docs/can.md). No vcan or kernel module needed.

    server: < hi >                      client: < open CHANNEL >    server: < ok >
    client: < rawmode >                 server: < ok >
    server: < frame ID SEC.USEC DATA >  (device -> host; time stamps are device time)
    client: < send ID LEN B0 B1 ... >   (host -> device)

One controlling client at a time: while one has its channel open, a second is refused (`< error busy
... >`, counted, reported on stderr); a connection that never opened a channel (a probe) is replaced.
When the client goes away the device runs on in real time, so its heartbeat timeout
stops the motor as on a rig, and the next client may connect. Pacing as in server.py.
"""

from __future__ import annotations

import contextlib
import select
import signal
import socket
import sys
import time
from collections.abc import Callable

from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.emulator.server import Pacer, ParentWatch, StateReporter

MAX_PENDING = 1 << 16  # octets of text waiting for the client before the device pauses
CHANNEL = "emu0"


def format_frames(frames: list[tuple[int, bytes, int]], ts_s: float) -> bytes:
    out = []
    for ident, data, isr in frames:
        t = isr * ts_s
        sec = int(t)
        out.append(f"< frame {ident:03X} {sec}.{round((t - sec) * 1e6):06d} {data.hex().upper()} >")
    return "".join(out).encode("ascii")


class SocketcandServer:
    def __init__(
        self,
        device: EmulatedDevice,
        host: str = "127.0.0.1",
        port: int = 0,
        channel: str = CHANNEL,
        pace: float | None = None,
    ):
        self.dev = device
        self.pacer = Pacer(pace=pace)
        self.channel = channel
        self.lsock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.lsock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.lsock.bind((host, port))
        self.lsock.listen(1)
        self.lsock.setblocking(False)
        self.host, self.port = self.lsock.getsockname()[:2]
        self.client: socket.socket | None = None
        self._inbuf = ""
        self._pending = bytearray()
        self._raw = False  # handshake done
        self._forward = False  # the client has sent a frame: device output goes to it
        self._stop = False
        self.frames_in = 0
        self.frames_out = 0
        self.refused = 0  # second clients refused while a session was connected
        self.ts_s = device.get("ts_s")

    @property
    def spec(self) -> str:
        return f"socketcand:{self.channel}@{self.host}:{self.port}"

    def stop(self, *_args: object) -> None:
        self._stop = True

    # ------------------------------------------------------------------ client handling
    def _drop_client(self) -> None:
        if self.client is not None:
            with contextlib.suppress(OSError):
                self.client.close()
        self.client = None
        self.pacer.host_gone()
        self._inbuf = ""
        self._pending.clear()
        self._raw = self._forward = False

    def _accept(self) -> None:
        try:
            c, _ = self.lsock.accept()
        except BlockingIOError:
            return
        if self.client is not None and self._raw and self._alive():
            # one controlling session at a time: a second client may not take over a running
            # motor (its heartbeats would keep it running unsupervised); refused, and said so
            self.refused += 1
            with contextlib.suppress(OSError):
                c.sendall(b"< error busy: another host controls this drive >")
            c.close()
            print(
                f"refused a second CAN client: a controlling session is connected "
                f"({self.refused} refused)",
                file=sys.stderr,
                flush=True,
            )
            return
        if self.client is not None:  # the old one is gone, or a probe that never opened a channel
            self._drop_client()
        c.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.client = c
        self.pacer.host_back()
        c.sendall(b"< hi >")
        c.setblocking(False)

    def _alive(self) -> bool:
        """Whether the current client's connection is still open (a peek, nothing consumed)."""
        if self.client is None:
            return False
        try:
            return self.client.recv(1, socket.MSG_PEEK) != b""
        except BlockingIOError:
            return True
        except OSError:
            return False

    def _handle(self, cmd: str) -> None:
        parts = cmd.split()
        if not parts:
            return
        if parts[0] == "send" and self._raw and len(parts) >= 3:
            try:
                ident = int(parts[1], 16)
                n = int(parts[2], 16)
                data = bytes(int(b, 16) for b in parts[3 : 3 + n])
            except ValueError:
                return
            self.frames_in += 1
            self._forward = True
            self.dev.can_rx(ident, data)
        elif parts[0] == "open":
            self._reply("< ok >" if len(parts) > 1 else "< error >")
        elif parts[0] == "rawmode":
            self._raw = True
            self._reply("< ok >")
        elif parts[0] == "echo":
            self._reply("< echo >")

    def _reply(self, text: str) -> None:
        if self.client is None:
            return
        try:
            self.client.sendall(text.encode("ascii"))
        except OSError:
            self._drop_client()

    def _read_client(self) -> None:
        if self.client is None:
            return
        try:
            data = self.client.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._drop_client()
            return
        self._inbuf += data.decode("ascii", errors="replace")
        while self.client is not None:
            start = self._inbuf.find("<")
            end = self._inbuf.find(">", start + 1)
            if start < 0 or end < 0:
                if start < 0:
                    self._inbuf = ""
                break
            cmd = self._inbuf[start + 1 : end]
            self._inbuf = self._inbuf[end + 1 :]
            self._handle(cmd)

    # ------------------------------------------------------------------ main loop
    def serve(
        self, reporter: StateReporter | None = None, watch: ParentWatch | None = None
    ) -> None:
        while not self._stop:
            if reporter is not None:
                reporter.poll()
            if watch is not None and watch.done(time.monotonic()):
                break
            now = time.monotonic()
            active = self.dev.active
            ticks = self.pacer.allowance(self.dev, now) if active else 0
            if not active:
                self.pacer.idle()
            can_run = len(self._pending) < MAX_PENDING
            busy = active and ticks > 0 and can_run
            rl = [self.lsock] + ([self.client] if self.client is not None else [])
            wl = [self.client] if self.client is not None and self._pending else []
            r, _w, _ = select.select(rl, wl, [], 0.0 if busy else 0.002)
            if self.lsock in r:
                self._accept()
            if self.client is not None and self.client in r:
                self._read_client()
            if can_run:
                self.dev.run(ticks if active else 0)
                frames = self.dev.can_take()
                if frames:
                    self.frames_out += len(frames)
                    if self.client is not None and self._forward:
                        self._pending += format_frames(frames, self.ts_s)
            if self.client is not None and self._pending:
                try:
                    n = self.client.send(self._pending)
                    del self._pending[:n]
                except BlockingIOError:
                    pass
                except OSError:
                    self._drop_client()

    def close(self) -> None:
        self._drop_client()
        with contextlib.suppress(OSError):
            self.lsock.close()


def serve_socketcand(
    settings: dict[str, float],
    announce: Callable[[str], object] = print,
    port: int = 0,
    pace: float | None = None,
    report_state: bool = False,
    parent_pid: int | None = None,
) -> None:
    """Run the emulator on a socketcand endpoint, printing `can: SPEC`, until SIGINT/SIGTERM."""
    dev = EmulatedDevice(settings)
    server = SocketcandServer(dev, port=port, pace=pace)
    signal.signal(signal.SIGTERM, server.stop)
    signal.signal(signal.SIGINT, server.stop)
    spec = server.spec
    bitrate = int(settings.get("can_bitrate", 1_000_000))
    node = int(settings.get("can_node", 1))
    from pmsm_hil.protocol import can_generated as cg

    if bitrate != cg.BITRATE:
        spec += f",bitrate={bitrate}"
    if node != cg.NODE:
        spec += f",node={node}"
    announce(f"can: {spec}")
    sys.stdout.flush()
    try:
        server.serve(
            StateReporter(dev) if report_state else None,
            ParentWatch(dev, parent_pid) if parent_pid else None,
        )
    finally:
        server.close()
