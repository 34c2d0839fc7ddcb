"""Serial transport over pyserial (a USB-UART to the F28335's SCI, or the emulator's pty)."""

from __future__ import annotations

import contextlib
import os
import select

import serial

from pmsm_hil.transport.base import TransportError

READ_MAX = 1 << 16  # octets gathered by one read() while the link keeps delivering


def _read_ready(fd: int, most: int = READ_MAX) -> bytes:
    """At most ``most`` of the octets waiting on a non-blocking descriptor; b"" when none (a tty in
    raw mode with VMIN = VTIME = 0, as pyserial sets it, reads 0 octets then rather than failing
    with EAGAIN)."""
    try:
        return os.read(fd, most)
    except BlockingIOError:
        return b""


class SerialTransport:
    def __init__(self, port: str, baud: int = 921600):
        if not os.path.exists(port):
            raise TransportError(f"serial port {port} does not exist (is the adapter plugged in?)")
        try:
            self._ser = serial.Serial(
                port, baudrate=baud, timeout=0, write_timeout=2.0, exclusive=True
            )
        except serial.SerialException as e:
            text = str(e)
            if "busy" in text.lower() or "lock" in text.lower() or "Errno 16" in text:
                raise TransportError(
                    f"serial port {port} is busy: another program has it open"
                ) from e
            if "Inappropriate ioctl" in text or "(25," in text or "Errno 25" in text:
                raise TransportError(
                    f"{port} is not a serial port: the OS says it is no terminal device "
                    "(give the adapter's port, e.g. /dev/ttyUSB0 or /dev/ttyACM0)"
                ) from e
            if "Permission denied" in text or "Errno 13" in text:
                raise TransportError(
                    f"serial port {port}: permission denied (add yourself to the 'dialout' group)"
                ) from e
            raise TransportError(f"serial port {port} cannot be opened: {text}") from e
        fd = getattr(self._ser, "fd", None)  # posix: the port's descriptor, opened non-blocking
        self._fd: int | None = fd if isinstance(fd, int) else None
        self.name = f"serial {port} @ {baud}"
        self.port = port
        self.bit_rate = float(baud)

    def write(self, data: bytes) -> None:
        """All of ``data``: written at once when the port takes it (the common case: a command
        or a heartbeat of a few octets), else the rest through pyserial, which waits for the port
        up to its write timeout."""
        try:
            if self._fd is not None:
                try:
                    n = os.write(self._fd, data)
                except BlockingIOError:
                    n = 0
                if n == len(data):
                    return
                data = data[n:]
            self._ser.write(data)
        except (serial.SerialException, OSError) as e:
            raise TransportError(f"link on {self.port} dropped while writing: {e}") from e

    def read(self, timeout_s: float) -> bytes:
        """What has arrived, waiting up to timeout_s for the first octet; while more keeps
        arriving, up to READ_MAX octets in one call (a pty hands over at most 4 KiB a read: the
        host's work per receive batch is then spread over more frames). Reads the port's file
        descriptor directly (pyserial opens it non-blocking); a port that reports data and gives
        none has gone (unplugged), as pyserial judges it."""
        if self._fd is None:
            return self._read_pyserial(timeout_s)
        fd = self._fd
        try:
            got = _read_ready(fd)
            if not got:
                ready, _, _ = select.select([fd], [], [], timeout_s)
                if not ready:
                    return b""
                got = _read_ready(fd)
                if not got:  # readable, yet nothing to read: the port has gone
                    raise OSError("the port reports data but gives none (disconnected?)")
            parts, size = [got], len(got)
            while size < READ_MAX:
                more = _read_ready(fd, READ_MAX - size)  # a pty may hand over more than 4 KiB
                if not more:
                    break
                parts.append(more)
                size += len(more)
            return got if len(parts) == 1 else b"".join(parts)
        except OSError as e:
            raise TransportError(f"link on {self.port} dropped while reading: {e}") from e

    def _read_pyserial(self, timeout_s: float) -> bytes:
        try:
            n = self._ser.in_waiting
            if n:
                return self._ser.read(n)
            self._ser.timeout = timeout_s
            first = self._ser.read(1)
            self._ser.timeout = 0
            if not first:
                return b""
            n = self._ser.in_waiting
            return first + (self._ser.read(n) if n else b"")
        except (serial.SerialException, OSError) as e:
            raise TransportError(f"link on {self.port} dropped while reading: {e}") from e

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._ser.close()
