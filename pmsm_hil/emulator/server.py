"""The emulator process: the firmware core + sim board behind a pseudo-terminal.

Device time runs as fast as the host keeps up, but never more than half the firmware's heartbeat
timeout ahead of the last heartbeat it received. When the host falls silent the emulator falls back
to real time, so the firmware's heartbeat timeout fires after the same wall time as on a rig.
With a pace X (`--pace`), device time never runs faster than X times wall time either.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import signal
import sys
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TextIO

from pmsm_hil.emulator.fwlib import EmulatedDevice

CHUNK_TICKS = 1000  # control periods per call into C (50 ms of device time at 50 us)
MAX_PENDING = 1 << 16  # octets waiting for the host before the emulator pauses


@dataclass
class Pacer:
    """Decides how many control periods may run now (see the module docstring).

    Unpaced: up to half the heartbeat timeout ahead of the last heartbeat. When the host is silent
    beyond that, the device waits `grace_s` of wall time (a slow host on a loaded machine is not a
    lost one; device time does not advance meanwhile), then runs on in real time, so the firmware's
    heartbeat timeout stops the motor within the same device time as on a rig.
    Paced (X): device time runs at X times wall time whatever the host does, as a DSP's clock does.
    """

    lead_fraction: float = 0.5
    pace: float | None = None  # X times real time (None: as fast as the host keeps up)
    grace_s: float = 1.0
    _last_hb: int = -1
    _gone: bool = False
    _anchor: tuple[float, int] | None = field(default=None)
    _pace_anchor: tuple[float, int] | None = field(default=None)

    def host_gone(self) -> None:
        """The host's connection is gone for certain: no grace, real time from now."""
        self._gone = True
        self._anchor = None

    def host_back(self) -> None:
        """A host has connected."""
        self._gone = False

    def allowance(self, dev: EmulatedDevice, now: float) -> int:
        ts_s = dev.get("ts_s")
        if self.pace is None:
            return self._heartbeat_allowance(dev, now, ts_s)
        isr = dev.isr_count
        if self._pace_anchor is None or isr < self._pace_anchor[1]:
            self._pace_anchor = (now, isr)
        paced = int((now - self._pace_anchor[0]) * self.pace / ts_s) - (isr - self._pace_anchor[1])
        return max(0, min(paced, CHUNK_TICKS))

    def idle(self) -> None:
        """The device is not running: the pace restarts from the next start."""
        self._pace_anchor = None

    def _heartbeat_allowance(self, dev: EmulatedDevice, now: float, ts_s: float) -> int:
        timeout = dev.get("heartbeat_timeout_s") or 0.5
        lead_ticks = int(self.lead_fraction * timeout / ts_s)
        hb, isr = dev.heartbeat_isr, dev.isr_count
        if hb != self._last_hb:
            self._last_hb = hb
            if not self._gone:
                self._anchor = None
        ahead = hb + lead_ticks - isr
        if ahead > 0 and not self._gone:
            return min(ahead, CHUNK_TICKS)
        if self._anchor is None:
            self._anchor = (now + (0.0 if self._gone else self.grace_s), isr)
        real_time = int((now - self._anchor[0]) / ts_s) - (isr - self._anchor[1])
        return max(0, min(real_time, CHUNK_TICKS))


class StateReporter:
    """`emulate --report-state`: one line on stdout each time the device's state changes, with
    the device time and the device time since the last heartbeat, so that whoever started the
    emulator sees when (in device time) a lost host got its motor stopped."""

    def __init__(self, device: EmulatedDevice, out: TextIO | None = None):
        from pmsm_hil.protocol import generated as gen

        self.dev = device
        self.out = out or sys.stdout
        self.names = {v: k for k, v in gen.ENUMS["state"].items()}
        self.ts_s = device.get("ts_s")
        self.last = device.state
        self.seen_isr = device.isr_count  # the control periods run when `last` was last seen

    def poll(self) -> None:
        state = self.dev.state
        if state == self.last:
            self.seen_isr = self.dev.isr_count
            return
        self.last = state
        isr, hb = self.dev.state_change()  # the last change a control period saw
        if isr <= self.seen_isr:  # none saw this one yet: a command made it (start, stop, abort)
            isr, hb = self.dev.isr_count, self.dev.heartbeat_isr
        self.seen_isr = self.dev.isr_count
        print(
            f"state: {self.names.get(state, state)} t_s={isr * self.ts_s:.6f} "
            f"since_heartbeat_s={(isr - hb) * self.ts_s:.6f}",
            file=self.out,
            flush=True,
        )


class ParentWatch:
    """For an emulator started by a host (`--exit-with-parent`): once that host process is gone
    (killed, crashed) and the drive is at rest, the emulator ends. Its motor is stopped first, by
    the heartbeat timeout, as on a rig; a lost host leaves no emulator behind."""

    CHECK_S = 0.2

    def __init__(self, device: EmulatedDevice, parent_pid: int):
        self.dev = device
        self.parent_pid = parent_pid
        self._next = 0.0

    def done(self, now: float) -> bool:
        if now < self._next:
            return False
        self._next = now + self.CHECK_S
        return os.getppid() != self.parent_pid and not self.dev.active


def _link_noise(flip_ppm: float, drop_ppm: float, seed: int):
    """A noisy line, or None for a clean one: then the child imports no numpy (some 60 ms of its
    start, which every `pmsm-hil run` waits for)."""
    if not (flip_ppm or drop_ppm):
        return None
    from pmsm_hil.emulator.link_noise import LinkNoise

    return LinkNoise(flip_ppm, drop_ppm, seed)


class PtyServer:
    """Serves one EmulatedDevice on a pty until stopped."""

    def __init__(
        self,
        device: EmulatedDevice,
        corrupt_ppm: float = 0.0,
        seed: int = 1,
        pace: float | None = None,
        drop_ppm: float = 0.0,
        noise_h2d: bool = False,
    ):
        self.dev = device
        self.pacer = Pacer(pace=pace)
        self.corrupt = _link_noise(corrupt_ppm, drop_ppm, seed)  # device -> host
        # host -> device: the same rates, another stream of the same seed
        self.noise_h2d = _link_noise(corrupt_ppm, drop_ppm, seed + 7919) if noise_h2d else None
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self._pending = bytearray()
        self._stop = False
        self.dropped_octets = 0  # the host not reading: what a full UART FIFO loses
        self._last_drain = time.monotonic()

    def stop(self, *_args: object) -> None:
        self._stop = True

    def serve(
        self, reporter: StateReporter | None = None, watch: ParentWatch | None = None
    ) -> None:
        while not self._stop:
            if reporter is not None:
                reporter.poll()
            now = time.monotonic()
            if watch is not None and watch.done(now):
                break
            if self.dev.active:
                ticks_allowed = self.pacer.allowance(self.dev, now)
            else:
                ticks_allowed = 0
                self.pacer.idle()
            # A device whose host does not read runs on like a DSP whose UART FIFO is full (the
            # output is dropped): always when paced, else once the backlog has not moved for the
            # pacer's grace time (a killed or stopped host), so its heartbeat timeout stops the motor.
            if not self._pending:
                self._last_drain = now
            stalled = now - self._last_drain > self.pacer.grace_s
            can_run = len(self._pending) < MAX_PENDING or self.pacer.pace is not None or stalled
            busy = self.dev.active and ticks_allowed > 0 and can_run
            wait = 0.0 if busy else 0.002
            rlist, _wlist, _ = select.select(
                [self.master], [self.master] if self._pending else [], [], wait
            )
            if rlist:
                try:
                    data = os.read(self.master, 65536)
                except OSError as e:  # EIO: no reader on the slave side right now
                    if e.errno not in (errno.EIO, errno.EAGAIN):
                        raise
                    data = b""
                if self.noise_h2d is not None and data:
                    data = self.noise_h2d(data)
                self.dev.rx(data)
            if can_run:
                _, out = self.dev.run(ticks_allowed if self.dev.active else 0)
                if self.corrupt is not None and out:
                    out = self.corrupt(out)
                if len(self._pending) < MAX_PENDING:
                    self._pending += out
                else:
                    self.dropped_octets += len(out)
            if self._pending:
                try:
                    n = os.write(self.master, self._pending)
                    del self._pending[:n]
                    if n:
                        self._last_drain = now
                except OSError as e:
                    if e.errno not in (errno.EAGAIN, errno.EIO):
                        raise

    def close(self) -> None:
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


def serve_pty(
    settings: dict[str, float],
    announce: Callable[[str], object] = print,
    corrupt_ppm: float = 0.0,
    pace: float | None = None,
    report_state: bool = False,
    parent_pid: int | None = None,
    drop_ppm: float = 0.0,
    noise_h2d: bool = False,
) -> None:
    """Run the emulator on a pty, printing `serial: PATH`, until SIGINT/SIGTERM."""
    dev = EmulatedDevice(settings)
    server = PtyServer(
        dev,
        corrupt_ppm,
        int(settings.get("seed", 1)),
        pace=pace,
        drop_ppm=drop_ppm,
        noise_h2d=noise_h2d,
    )
    signal.signal(signal.SIGTERM, server.stop)
    signal.signal(signal.SIGINT, server.stop)
    announce(f"serial: {server.path}")
    sys.stdout.flush()
    try:
        server.serve(
            StateReporter(dev) if report_state else None,
            ParentWatch(dev, parent_pid) if parent_pid else None,
        )
    finally:
        server.close()
