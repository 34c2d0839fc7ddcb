"""The serial transport on a pty (what a USB-UART or the emulator looks like to the host): one
read gathers what keeps arriving (a pty hands over at most 4 KiB a read), waits for the first
octet no longer than asked, and a port that goes away is a TransportError; writes arrive whole."""

from __future__ import annotations

import contextlib
import os
import pty
import threading
import time

import pytest

from pmsm_hil.errors import TransportError
from pmsm_hil.transport.serial_port import READ_MAX, SerialTransport


@pytest.fixture
def port():
    master, slave = pty.openpty()
    tr = SerialTransport(os.ttyname(slave))
    yield master, tr
    tr.close()
    os.close(slave)
    with contextlib.suppress(OSError):
        os.close(master)


def test_a_read_gathers_more_than_one_pty_buffer(port):
    master, tr = port
    data = bytes(range(256)) * 64  # 16 KiB, four times what one pty read hands over
    writer = threading.Thread(target=_write_all, args=(master, data))
    writer.start()
    time.sleep(0.2)  # the pty holds what it can
    first = tr.read(0.5)
    assert len(first) > 4096
    rest = b""
    deadline = time.monotonic() + 5
    while len(first) + len(rest) < len(data) and time.monotonic() < deadline:
        rest += tr.read(0.2)
    writer.join()
    assert first + rest == data


def test_reads_stop_at_the_bound(port):
    master, tr = port
    data = b"\x55" * (READ_MAX + 20000)
    writer = threading.Thread(target=_write_all, args=(master, data))
    writer.start()
    first = b""
    while not first:
        first = tr.read(1.0)
    rest = b""
    while len(first) + len(rest) < len(data):
        rest += tr.read(1.0)
    writer.join()
    assert 0 < len(first) <= READ_MAX + 4096
    assert first + rest == data


def test_nothing_arrives_within_the_timeout(port):
    _master, tr = port
    t0 = time.monotonic()
    assert tr.read(0.1) == b""
    assert 0.08 <= time.monotonic() - t0 < 1.0
    assert tr.read(0.0) == b""


def test_writes_arrive_whole(port):
    master, tr = port
    tr.write(b"hello\x00")
    time.sleep(0.05)
    assert os.read(master, 100) == b"hello\x00"


def test_a_port_that_goes_away_is_an_error(port):
    master, tr = port
    os.write(master, b"last words")
    assert tr.read(0.5) == b"last words"
    os.close(master)
    with pytest.raises(TransportError, match="dropped while reading"):
        for _ in range(10):
            tr.read(0.2)


def _write_all(fd: int, data: bytes) -> None:
    while data:
        try:
            n = os.write(fd, data[:8192])
        except BlockingIOError:
            time.sleep(0.001)
            continue
        data = data[n:]
