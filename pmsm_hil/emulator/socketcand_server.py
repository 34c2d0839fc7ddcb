"""The emulator on a CAN endpoint: the socketcand protocol (raw mode) on 127.0.0.1, which python-can's
`socketcand` interface speaks (docs/can.md). No vcan or kernel module needed.

    server: < hi >                      client: < open CHANNEL >    server: < ok >
    client: < rawmode >                 server: < ok >
    server: < frame ID SEC.USEC DATA >  (bus traffic; time stamps are device time)
    client: < send ID LEN B0 B1 ... >   (onto the bus)

The endpoint is a bus: several clients may have the channel open at once. Every frame the device
sends goes to every client; a frame a client sends goes to the device and to every other client
(not back to its sender), as other nodes on a bus see it. So python-can (`can.logger`, `can.viewer`,
a script with the DBC) can listen beside `pmsm-hil run`. What each client is (a probe, a listener,
a node) and how its queue fills: socketcand_client.py.

Pacing as in server.py, and a listener never slows the device: its frames are dropped when its
queue is full (counted, said on stderr when it leaves). A node (a client that has sent a frame,
the host) holds the device while its queue is full, until it has read. When the last node goes
away the device runs on in real time, so its heartbeat timeout stops the motor as on a rig;
listeners send no heartbeats and keep nothing running. A probe (a connection that never opens a
channel) gets no frames; when all places are taken the oldest probe makes way.
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
from pmsm_hil.emulator.socketcand_client import BusClient, format_frame, format_frames

CHANNEL = "emu0"
MAX_CLIENTS = 16  # connections at once (probes, listeners and nodes)
# the kernel's send buffer for each client (Linux allots twice this): fixed, so that a listener
# that lags loses frames (counted) behind MAX_PENDING and this, rather than receiving them seconds
# late from a buffer the kernel grows to megabytes
SEND_BUFFER_OCTETS = 1 << 16


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
        self.lsock.listen(MAX_CLIENTS)
        self.lsock.setblocking(False)
        self.host, self.port = self.lsock.getsockname()[:2]
        self.clients: list[BusClient] = []
        self._stop = False
        self.frames_in = 0  # frames clients sent onto the bus
        self.frames_out = 0  # frames the device sent
        self.refused = 0  # connections refused: all places taken, none by a probe
        self.ts_s = device.get("ts_s")

    @property
    def spec(self) -> str:
        return f"socketcand:{self.channel}@{self.host}:{self.port}"

    def stop(self, *_args: object) -> None:
        self._stop = True

    # ------------------------------------------------------------------ clients
    def _drop_client(self, client: BusClient) -> None:
        """It is gone (or the server closes): the last node gone means the host is gone."""
        client.close()
        if client in self.clients:
            self.clients.remove(client)
        if client.frames_dropped:
            print(
                f"CAN listener {client.name} left: {client.frames_dropped} frames dropped for it "
                f"(it did not read as fast as the bus ran; the drive did not wait for it)",
                file=sys.stderr,
                flush=True,
            )
        if client.is_node and not any(c.is_node for c in self.clients):
            self.pacer.host_gone()

    def _accept(self, now_s: float) -> None:
        try:
            sock, _ = self.lsock.accept()
        except BlockingIOError:
            return
        if len(self.clients) >= MAX_CLIENTS:
            probe = next((c for c in self.clients if c.is_probe), None)
            if probe is None:
                self.refused += 1
                with contextlib.suppress(OSError):
                    sock.sendall(b"< error busy: %d clients are connected >" % MAX_CLIENTS)
                sock.close()
                print(
                    f"refused a CAN client: {MAX_CLIENTS} clients are connected "
                    f"({self.refused} refused)",
                    file=sys.stderr,
                    flush=True,
                )
                return
            self._drop_client(probe)  # the oldest connection that never opened a channel
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_OCTETS)
            sock.sendall(b"< hi >")
            sock.setblocking(False)
        except OSError:  # gone already (a probe that only checked the port)
            sock.close()
            return
        self.clients.append(BusClient(sock, now_s))

    def _read(self, client: BusClient, now_s: float) -> None:
        was_node = client.is_node
        frames = client.read(now_s)
        if frames is None:
            self._drop_client(client)
            return
        if not frames:
            return
        if not was_node and not any(c.is_node for c in self.clients if c is not client):
            self.pacer.host_back()  # the first node: a host is here
        t_s = self.dev.isr_count * self.ts_s
        texts = []
        for ident, data, extended in frames:
            self.frames_in += 1
            self.dev.can_rx(ident, data)
            texts.append(format_frame(ident, data, t_s, extended))
        self._broadcast(texts, now_s, sender=client)

    def _broadcast(self, texts: list[bytes], now_s: float, sender: BusClient | None = None) -> None:
        for c in self.clients:
            if c is not sender and c.receives(now_s):
                c.queue(texts)

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
            can_run = not any(c.holds_device for c in self.clients)
            busy = active and ticks > 0 and can_run
            rl = [self.lsock] + [c.sock for c in self.clients]
            wl = [c.sock for c in self.clients if c.pending]
            r, w, _ = select.select(rl, wl, [], 0.0 if busy else 0.002)
            if self.lsock in r:
                self._accept(now)
            for c in [c for c in self.clients if c.sock in r]:
                self._read(c, now)
            if can_run:
                self.dev.run(ticks if active else 0)
                frames = self.dev.can_take()
                if frames:
                    self.frames_out += len(frames)
                    self._broadcast(format_frames(frames, self.ts_s), now)
            # a node's text goes at once; a listener's when its socket takes it (one that does
            # not read costs no failed send each turn)
            for c in [c for c in self.clients if c.pending and (c.is_node or c.sock in w)]:
                if not c.flush():
                    self._drop_client(c)

    def close(self) -> None:
        for c in list(self.clients):
            self._drop_client(c)
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
