"""Both names of the Foxglove WebSocket protocol on one port: a relay in front of foxglove-sdk.

foxglove-sdk (0.30) accepts only the subprotocol name `foxglove.sdk.v1` in the WebSocket handshake;
the protocol it names is the one clients know as `foxglove.websocket.v1`, the only name that
PlotJuggler, older Lichtblick releases and Foxglove releases before the SDK offer. Those clients
get "400 Bad Request" from the SDK's server. The relay listens on the user's port, and for each
connection:
- reads the client's handshake request; where it offers `foxglove.websocket.v1` and not
  `foxglove.sdk.v1`, the offer is renamed to the SDK's name (the accept key depends only on
  `Sec-WebSocket-Key`, so the handshake stays valid);
- passes the request to the SDK's server (127.0.0.1, a port of its own), and its answer back with
  the chosen name renamed to the one the client asked for;
- then copies the octets both ways unchanged: the frames do not carry the name.

A client that offers the SDK's name, or no Foxglove name, sees the SDK's server as it is.
"""

from __future__ import annotations

import contextlib
import re
import socket
import threading

SDK_NAME = b"foxglove.sdk.v1"
OLD_NAME = b"foxglove.websocket.v1"
MAX_HEADER = 16384  # octets of a handshake's header
_PROTO = re.compile(rb"(?im)^(sec-websocket-protocol:)([^\r\n]*)(?=\r?\n|\Z)")


def offered(request: bytes) -> list[bytes]:
    """The subprotocol names a handshake request offers, in its order."""
    names: list[bytes] = []
    for m in _PROTO.finditer(request):
        names += [n.strip() for n in m.group(2).split(b",") if n.strip()]
    return names


def rename(header: bytes, old: bytes, new: bytes) -> bytes:
    """`header` with the subprotocol name `old` replaced by `new` in Sec-WebSocket-Protocol."""

    def one(m: re.Match[bytes]) -> bytes:
        names = [n.strip() for n in m.group(2).split(b",")]
        return m.group(1) + b" " + b", ".join(new if n == old else n for n in names)

    return _PROTO.sub(one, header)


def _read_header(sock: socket.socket) -> tuple[bytes, bytes]:
    """(the header up to and including its blank line, the octets read past it)."""
    buf = b""
    while b"\r\n\r\n" not in buf:
        if len(buf) > MAX_HEADER:
            raise ValueError("handshake header too long")
        chunk = sock.recv(4096)
        if not chunk:
            raise ConnectionError("closed during the handshake")
        buf += chunk
    end = buf.index(b"\r\n\r\n") + 4
    return buf[:end], buf[end:]


def _pump(src: socket.socket, dst: socket.socket) -> None:
    """Copy src to dst until either side closes; then close both."""
    try:
        while True:
            data = src.recv(65536)
            if not data:
                break
            dst.sendall(data)
    except OSError:
        pass
    finally:
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                s.close()


class NameRelay:
    """Listen on host:port (0: a free one) and relay to 127.0.0.1:upstream_port."""

    def __init__(self, host: str, port: int, upstream_port: int):
        self.upstream = ("127.0.0.1", upstream_port)
        self._sock = socket.create_server((host, port))  # OSError when the port is taken
        self.port = self._sock.getsockname()[1]
        self.renamed = 0  # connections whose name was renamed
        self._closed = False
        self._conns: set[socket.socket] = set()
        self._lock = threading.Lock()
        threading.Thread(target=self._accept, name="foxglove-relay", daemon=True).start()

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._sock.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(client,), daemon=True).start()

    def _track(self, *socks: socket.socket) -> bool:
        with self._lock:
            if self._closed:
                return False
            self._conns.update(socks)
            return True

    def _serve(self, client: socket.socket) -> None:
        up = None
        try:
            if not self._track(client):  # close() ends a handshake still under way too
                raise ConnectionError("relay closed")
            client.settimeout(10.0)
            request, rest = _read_header(client)
            names = offered(request)
            legacy = OLD_NAME in names and SDK_NAME not in names
            if legacy:
                request = rename(request, OLD_NAME, SDK_NAME)
            up = socket.create_connection(self.upstream, timeout=10.0)
            if not self._track(up):
                raise ConnectionError("relay closed")
            up.sendall(request + rest)
            answer, rest = _read_header(up)
            if legacy:
                answer = rename(answer, SDK_NAME, OLD_NAME)
                self.renamed += 1
            client.sendall(answer + rest)
            client.settimeout(None)
            up.settimeout(None)
        except (OSError, ValueError):
            for s in (client, up):
                if s is not None:
                    with contextlib.suppress(OSError):
                        s.close()
            self._untrack(client, up)
            return
        threading.Thread(target=_pump, args=(up, client), daemon=True).start()
        _pump(client, up)  # it closes both, which ends the other direction's copy too
        self._untrack(client, up)

    def _untrack(self, *socks: socket.socket | None) -> None:
        with self._lock:
            for s in socks:
                if s is not None:
                    self._conns.discard(s)

    def close(self) -> None:
        with self._lock:
            self._closed = True
            conns = list(self._conns)
        # shut down before the close: a close alone does not wake the accept() under way in
        # _accept (Linux), which would keep the port listening until a connection came
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_RDWR)
        with contextlib.suppress(OSError):
            self._sock.close()
        for s in conns:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                s.close()
