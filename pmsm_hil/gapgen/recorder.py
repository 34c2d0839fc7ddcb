"""A profile run on the in-process emulator with a continuous control-rate recording (simulation
only: the F28335 keeps only a 1024-sample capture buffer), written as `/pmsm/control_rate`."""

from __future__ import annotations

import ctypes
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pmsm_hil.device import DeviceSpec, emulator_settings_for
from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.gap.record import CONTROL_TOPIC, GAP_TOPICS
from pmsm_hil.log.reader import read_log
from pmsm_hil.log.writer import LogWriter
from pmsm_hil.profiles import Profile, load_profile
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, RunResult, run_profile
from pmsm_hil.transport.inproc import InProcessTransport

REC_COLS = (
    "t_s",
    "i_a_a",
    "i_b_a",
    "i_c_a",
    "s_a",
    "s_b",
    "s_c",
    "pwm_on",
    "v_dc_v",
    "theta_e_rad",
    "omega_e_rad_s",
    "load_nm",
)


@dataclass
class Recorded:
    """A recording: the control-rate columns written, how the run ended (a fault or a stop
    before the profile's end leaves a shorter record) and the profile it played."""

    cols: dict[str, np.ndarray]
    result: RunResult
    profile: Profile


def _bind(dev: EmulatedDevice):
    lib = dev._lib
    lib.emu_record.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint32]
    lib.emu_record_count.argtypes = [ctypes.c_void_p]
    lib.emu_record_count.restype = ctypes.c_uint32
    return lib


def record_profile(
    profile_path: str | os.PathLike,
    out_path: str | os.PathLike,
    rig_path: str | os.PathLike | None = None,
    seed: int = 1,
    full_log: bool = True,
    sensors: dict[str, float] | None = None,
    motor_path: str | os.PathLike | None = None,
) -> Recorded:
    """Run the profile in process with the rig, record every control period and write a log with
    `/pmsm/control_rate`. full_log: also every topic of the run and its metadata (a user's log);
    otherwise only the control-rate record, the motor attachment and `gap_sensors` (a sealed
    self-test log: nothing of the rig). motor_path: a motor file instead of the profile's (as `run
    --motor`). Returns the recorded columns with the run's result."""
    profile = load_profile(str(profile_path), rig_override=rig_path, motor_override=motor_path)
    settings = emulator_settings_for(profile, DeviceSpec(seed=seed))
    if not full_log:
        settings["truth_hz"] = 0.0
    dev = EmulatedDevice(settings)
    lib = _bind(dev)
    n_max = round(profile.total_duration_s / profile.control.ts_s) + 16
    buf = np.zeros((n_max, len(REC_COLS)), dtype=np.float64)
    lib.emu_record(dev._p, buf.ctypes.data, n_max)
    transport = InProcessTransport(settings, chunk_ticks=4000, device=dev)
    fd, tmp = tempfile.mkstemp(suffix=".mcap")
    os.close(fd)
    try:
        result = run_profile(
            profile, Session(transport), Path(tmp), RunOptions(seed=seed, capture=full_log)
        )
        n = lib.emu_record_count(dev._p)
        lib.emu_record(dev._p, None, 0)
        cols = {k: buf[:n, j].copy() for j, k in enumerate(REC_COLS)}
        run_log = read_log(tmp)
        meta = {"gap_source": {"kind": "emulator", "ts_s": repr(profile.control.ts_s)}}
        if sensors:
            meta["gap_sensors"] = {k: repr(float(v)) for k, v in sensors.items()}
            if "encoder_lines" in sensors:  # the firmware reads a count as where it starts
                meta["gap_sensors"]["encoder_count_start"] = "1.0"
        atts = []
        if full_log:
            meta.update({k: v for k, v in run_log.metadata.items() if k != "log"})
            atts = [(a.name, a.media_type, a.data) for a in run_log.attachments]
        else:
            atts = [
                (a.name, a.media_type, a.data)
                for a in run_log.attachments
                if a.name == "motor.yaml"
            ]
        with LogWriter(out_path, meta, atts, topics=GAP_TOPICS) as w:
            if full_log:
                for topic in run_log.topics:
                    c = run_log.topic(topic)
                    if topic.startswith(("/pmsm/", "/sim/")) and len(c["t_s"]):
                        w.write_many(topic, c)
            w.write_many(CONTROL_TOPIC, cols)
    finally:
        os.unlink(tmp)
    return Recorded(cols, result, profile)
