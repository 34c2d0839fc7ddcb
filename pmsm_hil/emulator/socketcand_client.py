"""One connection to the emulator's socketcand endpoint (socketcand_server.py): its handshake, the
frames it sends, and the text waiting for it, with what it is on the bus (docs/can.md).

    probe     connected, no channel opened: gets no frames, is no node
    listener  channel open in raw mode, has sent no frame: gets every frame; when its queue is full
              further frames are dropped and counted (the device never waits for a listener)
    node      has sent a frame (the host of `pmsm-hil run`): gets every frame other than its own;
              when its queue is full the device waits for it (back-pressure)
"""

from __future__ import annotations

import contextlib
import socket

MAX_PENDING = 1 << 16  # octets of text waiting for a client: a node's pauses the device
# python-can's socketcand client reads each handshake reply with one recv() and wants exactly
# `< ok >`: a frame sent right behind the rawmode reply would spoil it. A listener gets frames
# from this long after its rawmode reply (a node from its first frame: it has read the reply).
LISTENER_SETTLE_S = 0.25
MAX_COMMAND_OCTETS = 4096  # text without a closing `>` beyond this is dropped (not a command)


def format_frame(ident: int, data: bytes, t_s: float, extended: bool = False) -> bytes:
    """A frame as socketcand sends it in raw mode: `< frame ID SEC.USEC DATA >`."""
    sec = int(t_s)
    usec = round((t_s - sec) * 1e6)
    if usec == 1_000_000:
        sec, usec = sec + 1, 0
    ident_text = f"{ident:08X}" if extended else f"{ident:03X}"
    return f"< frame {ident_text} {sec}.{usec:06d} {data.hex().upper()} >".encode("ascii")


def format_frames(frames: list[tuple[int, bytes, int]], ts_s: float) -> list[bytes]:
    """The device's frames [(identifier, data, control period)], each as its text."""
    return [format_frame(ident, data, isr * ts_s) for ident, data, isr in frames]


class BusClient:
    """A client connection: reads its commands, answers the handshake, queues text for it."""

    def __init__(self, sock: socket.socket, now_s: float):
        self.sock = sock
        try:
            host, port = sock.getpeername()[:2]
            self.name = f"{host}:{port}"
        except OSError:
            self.name = "a client"
        self.connected_s = now_s
        self.opened = False  # `< open CHANNEL >` answered
        self.raw_since_s: float | None = None  # when `< rawmode >` was answered
        self.is_node = False  # has sent a frame
        self.frames_sent = 0  # frames it sent onto the bus
        self.frames_dropped = 0  # frames for it not queued: its queue was full (listeners only)
        self.pending = bytearray()  # text waiting for it
        self._inbuf = ""

    @property
    def is_probe(self) -> bool:
        return not self.opened and self.raw_since_s is None

    def receives(self, now_s: float) -> bool:
        """Whether bus traffic goes to it now (see LISTENER_SETTLE_S)."""
        if self.raw_since_s is None:
            return False
        return self.is_node or now_s - self.raw_since_s >= LISTENER_SETTLE_S

    @property
    def holds_device(self) -> bool:
        """A node whose queue is full: the device waits until it has read."""
        return self.is_node and len(self.pending) >= MAX_PENDING

    def queue(self, texts: list[bytes]) -> None:
        """Bus traffic for it: all of it for a node (the server pauses the device while a node's
        queue is full); for a listener what fits, the rest dropped and counted."""
        if self.is_node:
            self.pending += b"".join(texts)
            return
        for i, text in enumerate(texts):
            if len(self.pending) >= MAX_PENDING:
                self.frames_dropped += len(texts) - i
                return
            self.pending += text

    def read(self, now_s: float) -> list[tuple[int, bytes, bool]] | None:
        """What it sent: the frames [(identifier, data, extended)] it put on the bus; handshake
        commands are answered (queued). None when the connection is closed or broken."""
        try:
            data = self.sock.recv(65536)
        except BlockingIOError:
            return []
        except OSError:
            return None
        if not data:
            return None
        self._inbuf += data.decode("ascii", errors="replace")
        frames: list[tuple[int, bytes, bool]] = []
        while True:
            start = self._inbuf.find("<")
            if start < 0:
                self._inbuf = ""
                break
            end = self._inbuf.find(">", start + 1)
            if end < 0:
                if len(self._inbuf) - start > MAX_COMMAND_OCTETS:
                    self._inbuf = ""
                break
            cmd = self._inbuf[start + 1 : end]
            self._inbuf = self._inbuf[end + 1 :]
            frame = self._handle(cmd.split(), now_s)
            if frame is not None:
                frames.append(frame)
        return frames

    def _handle(self, parts: list[str], now_s: float) -> tuple[int, bytes, bool] | None:
        if not parts:
            return None
        if parts[0] == "send" and self.raw_since_s is not None and len(parts) >= 3:
            try:
                ident = int(parts[1], 16)
                n = int(parts[2], 16)
                data = bytes(int(b, 16) for b in parts[3 : 3 + n])
            except ValueError:
                return None
            self.is_node = True
            self.frames_sent += 1
            return ident, data, len(parts[1]) > 3
        if parts[0] == "open":
            self.opened = self.opened or len(parts) > 1
            self.pending += b"< ok >" if len(parts) > 1 else b"< error >"
        elif parts[0] == "rawmode":
            if self.raw_since_s is None:
                self.raw_since_s = now_s
            self.pending += b"< ok >"
        elif parts[0] == "echo":
            self.pending += b"< echo >"
        return None

    def flush(self) -> bool:
        """Send what waits, as much as the socket takes; False when the connection is broken."""
        if not self.pending:
            return True
        try:
            n = self.sock.send(self.pending)
        except BlockingIOError:
            return True
        except OSError:
            return False
        del self.pending[:n]
        return True

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()
