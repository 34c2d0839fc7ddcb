"""A host that dies or freezes mid-run on the serial emulator: the device's clock runs on (its UART
output is dropped as a full FIFO would) and its heartbeat timeout stops the motor, measured in
device time from the emulator's own state."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.emulator.server import PtyServer
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import generated as gen

STATE = gen.ENUMS["state"]


@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGSTOP])
def test_lost_host_on_serial_stops_the_motor_within_the_heartbeat_time(data, tmp_path, how):
    profile = load_profile(str(data / "long.yaml"))
    settings = emulator_settings(profile.motor, profile.rig, seed=1, baud=profile.link.baud,
                                 ts_s=profile.control.ts_s)
    dev = EmulatedDevice(settings)
    server = PtyServer(dev)
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    host = subprocess.Popen([sys.executable, "-m", "pmsm_hil.cli.main", "run", str(data / "long.yaml"),
                             "--port", server.path, "--out", str(tmp_path / "lost.mcap"), "--no-live"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not (dev.state == STATE["running"]
                                                   and dev.isr_count * profile.control.ts_s > 1.0):
            time.sleep(0.01)
        assert dev.state == STATE["running"], "the run never started"
        os.kill(host.pid, how)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and dev.state == STATE["running"]:
            time.sleep(0.002)
        assert dev.state != STATE["running"], "the motor kept running without its host"
        ts = profile.control.ts_s
        silent_s = (dev.isr_count - dev.heartbeat_isr) * ts      # device time since the last heartbeat
        assert silent_s <= profile.control.heartbeat_timeout_s + 0.01   # + the sampling of this loop
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and dev.active:
            time.sleep(0.01)
        assert dev.state == STATE["idle"]          # brought to rest, PWM off
    finally:
        if how == signal.SIGSTOP:
            os.kill(host.pid, signal.SIGKILL)
        host.wait(timeout=10)
        server.stop()
        thread.join(timeout=5)
        server.close()
