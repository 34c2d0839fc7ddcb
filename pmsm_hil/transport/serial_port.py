"""Serial transport over pyserial (a USB-UART to the F28335's SCI, or the emulator's pty)."""

from __future__ import annotations

import contextlib
import os

import serial

from pmsm_hil.transport.base import TransportError


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
            if "Permission denied" in text or "Errno 13" in text:
                raise TransportError(
                    f"serial port {port}: permission denied (add yourself to the 'dialout' group)"
                ) from e
            raise TransportError(f"serial port {port} cannot be opened: {text}") from e
        self.name = f"serial {port} @ {baud}"
        self.port = port
        self.bit_rate = float(baud)

    def write(self, data: bytes) -> None:
        try:
            self._ser.write(data)
        except (serial.SerialException, OSError) as e:
            raise TransportError(f"link on {self.port} dropped while writing: {e}") from e

    def read(self, timeout_s: float) -> bytes:
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
