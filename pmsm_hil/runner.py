"""Plays a profile on a device (rig or emulator): configure, download, start, stream to the log,
keep the heartbeat, and end safely whatever happens (profile end, Ctrl-C, fault, dropped link)."""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from pmsm_hil import __version__
from pmsm_hil.control_design import calibration_config, device_config
from pmsm_hil.errors import DeviceError, TransportError
from pmsm_hil.interrupts import Interrupts as _Interrupts
from pmsm_hil.log.blocks import MessageBlock
from pmsm_hil.log.writer import LogWriteError, LogWriter
from pmsm_hil.profiles import Motor, Profile
from pmsm_hil.profiles.control_checks import profile_controllers
from pmsm_hil.profiles.motor import nominal_machine
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.session import Identity, Session
from pmsm_hil.recorder import LiveState, Recorder, Sink
from pmsm_hil.sensorless_design import estimator_frames

# The recorder hands every receive batch to the OS at its end (the log's journal,
# Recorder.frames); what the host writes on its own (events) goes out at least this often (wall
# time; docs/log-format.md).
LOG_FLUSH_WALL_S = 0.25
# wall time between heartbeats at most (a rig, or an emulator that waits for the host)
HEARTBEAT_WALL_S = 0.05
# with less (a paced emulator), a receive batch is recorded in slices of this many frames at most,
# a heartbeat between them when one is due: a batch of 64 KiB (some 1800 frames) took 30 ms and
# more with a Foxglove sink, longer than a device paced at 20x real time waits for one (25 ms);
# slices cost the host a fifth more CPU, so a batch is sliced only then
_SLICE_FRAMES = 256


@dataclass
class RunOptions:
    heartbeat_period_s: float = (
        0.02  # device time between heartbeats (also at least every heartbeat_wall_s)
    )
    # wall time between heartbeats at most, also within a long receive batch (its frames are
    # recorded in slices, a heartbeat between them when due): a device paced at X times real
    # time times out after its heartbeat timeout / X of wall time (`run --pace`: cli/run.py)
    heartbeat_wall_s: float = HEARTBEAT_WALL_S
    silent_after_s: float | None = None  # testing: stop sending heartbeats after this device time
    stop_after_s: float | None = None  # ask the device to stop after this device time
    device_timeout_s: float = 3.0  # no data for this long while running: the device is lost
    capture: bool = True  # upload the capture buffer at the end
    seed: int | None = None  # recorded in the metadata (the emulator's seed)
    rig_name: str = ""
    on_update_s: float = 0.1  # wall time between observer updates
    sinks: Sequence[Sink] = field(default_factory=list)  # extra consumers of each device message
    # further configuration messages sent after the profile, e.g. ("config_commission", {...})
    requests: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    # when received messages reach the OS (what a killed host still leaves in its log,
    # docs/faults.md): "batch" at the end of every batch read from the link, before the next read,
    # in the log's journal (a killed host loses nothing it received; about 5 % of the host's CPU
    # time); "wall" with the chunks only, at least every LOG_FLUSH_WALL_S of wall time
    log_sync: str = "batch"
    # asked while the run streams (at most every interrupts.STOP_POLL_S of wall time): a
    # non-empty answer, why, stops the motor as a Ctrl-C would (a sweep's runs in Dask workers)
    stop_requested: Callable[[], str] | None = None


@dataclass
class RunResult:
    log_path: Path
    state: str
    stop_reason: str
    faults: int
    interrupted: bool
    error: str = ""
    capture_samples: int = 0
    live: LiveState = field(default_factory=LiveState)


class Observer(Protocol):
    """What the runner tells while a run goes on (e.g. the CLI's step printer)."""

    def message(self, text: str) -> None: ...

    def update(self, live: LiveState) -> None: ...


class RunInterrupted(Exception):
    pass


COPPER_ALPHA_PER_K = 0.00393  # temperature coefficient of the winding's resistance
T_REF_C = 25.0  # the motor file's temperature


class PlantMismatch(DeviceError):
    """The emulator serves another motor than the profile's (it was started with other files)."""


def plant_mismatch(
    motor: Motor, truth: dict[str, Any], deviation: dict[str, float] | None = None
) -> str | None:
    """What differs between the emulator's plant (its first truth frame) and the profile's motor
    file, beyond what rig effects explain (temperature, saturation, and ``deviation``: the rig's
    motor_deviation factors, e.g. {"psi_f_wb": 2.0}); None when they match."""
    out = []
    temp = float(truth.get("temp_winding_c", 0.0) or 0.0)
    for key, unit, tol in (("psi_f_wb", "Wb", 0.2), ("r_s_ohm", "ohm", 0.6)):
        nominal, plant = float(getattr(motor, key)), float(truth.get(key, 0.0) or 0.0)
        nominal *= (deviation or {}).get(key, 1.0)
        if key == "r_s_ohm" and temp > 0.0 and math.isfinite(temp):
            # a winding the rig heats (a thermal effect, a fitted one up to 200 degC) is the
            # same motor: compare its resistance at the reference temperature
            plant /= 1.0 + COPPER_ALPHA_PER_K * (temp - T_REF_C)
        if plant and nominal and abs(plant / nominal - 1.0) > tol:
            out.append(
                f"{key} {plant:.4g} {unit} in the emulator vs {nominal:.4g} {unit} in {motor.name}"
            )
    if not out:
        return None
    return (
        "the emulator's plant is not this profile's motor (" + "; ".join(out) + "): start it with "
        "the same motor, e.g. `pmsm-hil emulate --profile PROFILE` or `--motor MOTOR.yaml`"
    )


class HostError(Exception):
    """The host failed during a run (e.g. the log could not be written); the motor was stopped."""


def _identity(session: Session) -> Identity:
    """The device's identity (from `session.hello()`, which every run starts with)."""
    if session.identity is None:
        raise DeviceError(f"the device on {session.t.name} has not been identified: hello first")
    return session.identity


def _metadata(profile: Profile, session: Session, options: RunOptions) -> dict[str, dict[str, str]]:
    ident = _identity(session)
    return {
        "run": {
            "profile": profile.name,
            "profile_path": str(profile.path),
            "motor": profile.motor.name,
            "rig": options.rig_name,
            "seed": "" if options.seed is None else str(options.seed),
            "host_version": __version__,
            "transport": session.t.name,
            "ts_s": repr(profile.control.ts_s),
            "segment_names": "|".join(
                s.name or f"segment {i}" for i, s in enumerate(profile.segments)
            ),
            # what controlled the currents in each segment, and where the angle came from
            "current_ctrl": "|".join(profile_controllers(profile)),
            "angle_src": profile.control.angle_src,
        },
        # the rig's effects in force and their sizes (docs/rigs.md); the rig yaml is attached too
        "rig_effects": profile.rig.effective_metadata(nominal_machine(profile.motor)),
        "device": {
            "board": ident.board,
            "fw_version": ident.fw_version,
            "proto_version": str(ident.proto_version),
            "schema_hash": f"{ident.schema_hash:08x}",
        },
    }


def _attachments(profile: Profile) -> list[tuple[str, str, bytes]]:
    out: list[tuple[str, str, bytes]] = []
    for label, text in profile.yaml_texts.items():
        out.append((label, "application/yaml", text.encode()))
    return out


def configure(session: Session, profile: Profile) -> None:
    """Send motor, control and profile to the device, each acknowledged."""
    motor_cfg, ctrl_cfg = device_config(profile)
    session.request("config_motor", **motor_cfg)
    session.request("config_ctrl", **ctrl_cfg)
    calib = calibration_config(profile.motor)
    if calib is not None:  # a commissioned motor file: the current sensors' calibration
        session.request("config_calib", **calib)
    if profile.control.angle_src in ("ripple_pll", "hybrid") or (
        profile.control.angle_src == "mras" and profile.motor.if_start_current_a
    ):
        # the ripple PLL's magnetics, polarity signature, hybrid band; the MRAS's I/f start
        # (docs/sensorless.md)
        snl_cfg, nodes = estimator_frames(profile.motor)
        session.request("config_sensorless", **snl_cfg)
        for node in nodes:
            session.request("gamma_node", **node)
    session.request("profile_clear", n_segments=len(profile.segments))
    for i, s in enumerate(profile.segments):
        session.request(
            "profile_segment",
            index=i,
            duration_s=s.duration_s,
            speed_rpm=s.speed_rpm,
            ramp_rpm_s=s.ramp_rpm_s,
            load_nm=s.load_nm,
            flags=s.flags,
            kind=gen.ENUMS["segment_kind"][s.kind],
            inject_a=s.inject_a,
            inject_hz=s.inject_hz,
        )
    steps = [(i, s.plant) for i, s in enumerate(profile.segments) if s.plant is not None]
    if steps and _identity(session).board == "emulator":
        for i, st in steps:  # emulator only: the sim board steps the true R and psi_f
            session.request(
                "sim_plant", index=i, r_s_scale=st.r_s_scale, psi_f_scale=st.psi_f_scale
            )


def run_profile(
    profile: Profile,
    session: Session,
    log_path: Path | str,
    options: RunOptions | None = None,
    observer: Observer | None = None,
) -> RunResult:
    """Run `profile` on the device behind `session`, logging to `log_path` (MCAP).

    Whatever ends the run (profile end, a signal, a fault, a dropped link, a host failure), the
    device is told to stop (then to abort) before this returns, and the log is finalised."""
    options = options or RunOptions()
    log_path = Path(log_path)
    session.hello()
    configure(session, profile)
    for name, fields in options.requests:
        session.request(name, **fields)
    if options.stop_after_s is not None:  # the device stops itself at that tick, exactly (an
        # emulator runs ahead of what the host has read); the host's own stop stays the fallback
        session.request("stop_at", tick=max(1, round(options.stop_after_s / profile.control.ts_s)))
    names = [s.name or f"segment {i}" for i, s in enumerate(profile.segments)]
    interrupted = False
    error = ""
    writer = LogWriter(
        log_path,
        _metadata(profile, session, options),
        _attachments(profile),
        wall_start_s=time.time(),
        flush_wall_s=LOG_FLUSH_WALL_S,
        journal=options.log_sync == "batch",
    )
    rec = Recorder(writer, profile.control.ts_s, names, options.sinks)
    rec.live.total_s = profile.total_duration_s
    safe = _SafeObserver(observer)
    try:
        with _Interrupts(options.stop_requested) as sig:
            try:
                session.request("start")
                rec.event(0.0, "host", 0, 0, f"started {profile.name} on {session.t.name}")
                dev = profile.rig.plant_factors()
                interrupted = _stream(session, rec, options, safe, sig, profile.motor, dev)
                if interrupted:
                    _stop_device(session, rec, safe, sig)
            except KeyboardInterrupt:  # raised outside the handlers (not the main thread)
                interrupted = True
                _stop_device(session, rec, safe, sig)
            except PlantMismatch:
                _send_quietly(session, "abort")
                raise
            except LogWriteError as e:  # a full disk: stop the motor under control, then report
                error = _stop_after_log_failure(session, rec, safe, sig, e)
            except (TransportError, DeviceError) as e:
                error = str(e)
                rec.event(rec.live.t_s, "host", 0, 0, f"link error: {error}")
                _send_quietly(session, "abort")
            except Exception as e:  # a host failure: stop the motor, then report it
                _send_quietly(session, "stop")
                _send_quietly(session, "abort")
                raise HostError(
                    f"{type(e).__name__}: {e}; stop and abort were sent to the device"
                ) from e
            safe.update(rec.live)  # the last state: a run over before the first update too
            n_cap = 0
            if options.capture and not error and not sig.count > 1:
                n_cap = _upload_capture(session, rec, safe)
            _write_link_stats(rec.w, session, rec)
    finally:
        writer.close()  # raises LogWriteError when the end of the log cannot be written
    live = rec.live
    return RunResult(
        log_path=log_path,
        state=live.state,
        stop_reason=live.stop_reason,
        faults=live.faults,
        interrupted=interrupted,
        error=error,
        capture_samples=n_cap if not error else 0,
        live=live,
    )


class _NoLog(LogWriter):
    """Stands in for a writer that failed: the live state goes on, nothing is written (it opens
    no file; only the message methods are meant to be called)."""

    def __init__(self) -> None:
        pass

    def write(self, topic: str, t_s: float, fields: Mapping[str, Any]) -> None:
        pass

    def fixed_layout(self, topic: str, strings: Mapping[str, str] | None = None) -> None:
        return None

    def message_block(self, topic: str, t_s: Any, data: Any) -> MessageBlock:
        return MessageBlock(topic, 0, 0, np.zeros(len(data), dtype=np.int64), data)

    def write_runs(self, runs: Iterable[tuple[MessageBlock, int]]) -> None:
        for block, stop in runs:
            block.pos = max(block.pos, stop)

    def write_many(self, topic: str, rows: Any) -> int:
        return 0

    def flush_if_due(self) -> None:
        pass

    def flush_batch(self) -> None:
        pass


def _stop_after_log_failure(
    session: Session, rec: Recorder, observer: Observer, sig: _Interrupts, err: LogWriteError
) -> str:
    """The log cannot be written: a controlled stop (abort after 5 s without it), as for Ctrl-C;
    returns the error for the exit message, with how the motor stopped and what the log holds."""
    rec.w = _NoLog()
    _stop_device(session, rec, observer, sig, reason=err.strerror or "")
    live = rec.live
    how = (
        f"the motor was stopped (device {live.state}, {live.stop_reason or 'stop'})"
        if live.stopped
        else "stop and abort were sent to the device"
    )
    return f"{err.strerror}; {how}; recover the log with `pmsm-hil log recover {err.path}`"


def _send_quietly(session: Session, what: str) -> None:
    with contextlib.suppress(Exception):  # the link is gone too: the device stops on its heartbeat
        session.send(what)


class _SafeObserver:
    """The live view must never end a run: a closed pipe or a terminal error silences it."""

    def __init__(self, observer: Observer | None):
        self.inner = observer

    def update(self, live: LiveState) -> None:
        self._call("update", live)

    def message(self, text: str) -> None:
        self._call("message", text)

    def _call(self, name: str, arg: LiveState | str) -> None:
        if self.inner is None:
            return
        try:
            getattr(self.inner, name)(arg)
        except (OSError, ValueError):  # BrokenPipeError, a closed or detached stream
            self.inner = None


def _stream(
    session: Session,
    rec: Recorder,
    options: RunOptions,
    observer: Observer | None,
    sig: _Interrupts,
    motor: Motor | None = None,
    deviation: dict[str, float] | None = None,
) -> bool:
    """Stream until the device stops (False) or a signal asks the host to stop (True)."""
    live = rec.live
    plant_checked = motor is None
    last_hb_dev = -1.0
    last_hb_wall = 0.0
    last_data_wall = time.monotonic()
    last_update = 0.0
    hb_counter = 0
    stop_sent = False

    def heartbeat(now: float) -> None:
        """Sent as a batch arrives, before it is recorded (the device runs on meanwhile), and
        between the slices of a long one."""
        nonlocal hb_counter, last_hb_dev, last_hb_wall
        silent = options.silent_after_s is not None and live.t_s >= options.silent_after_s
        if not silent and (
            live.t_s - last_hb_dev >= options.heartbeat_period_s
            or now - last_hb_wall >= options.heartbeat_wall_s
        ):
            session.send("heartbeat", counter=hb_counter)
            hb_counter = (hb_counter + 1) & 0xFFFFFFFF
            last_hb_dev, last_hb_wall = live.t_s, now

    while True:
        if sig.poll():
            return True
        frames = session.poll(0.02)
        now = time.monotonic()
        heartbeat(now)
        if frames:
            last_data_wall = now
            # "batch": on disk (the journal) before the link is read again; in slices when a
            # paced device waits less for its heartbeat than a whole batch may take
            step = _SLICE_FRAMES if options.heartbeat_wall_s < HEARTBEAT_WALL_S else len(frames)
            for at in range(0, len(frames), step):
                if at:
                    heartbeat(time.monotonic())
                rec.frames(frames[at : at + step])
            if not plant_checked and motor is not None and live.truth:
                plant_checked = True
                why = plant_mismatch(motor, live.truth, deviation)
                if why:
                    rec.event(live.t_s, "host", 0, 0, why)
                    raise PlantMismatch(why)
        if options.stop_after_s is not None and live.t_s >= options.stop_after_s and not stop_sent:
            if not live.stopped:  # the fallback: the device stops itself at that tick (stop_at)
                session.send("stop")
            stop_sent = True
            # at the tick the device stopped: the summary ends the last segment there, not after
            # the quick stop that the host's reading lags into
            t_stop = max(1, round(options.stop_after_s / rec.ts_s)) * rec.ts_s
            rec.event(min(live.t_s, t_stop), "host", 0, 0, "stop requested by the host")
        rec.w.flush_if_due()
        live.octets = session.decoder.octets
        live.bad_frames = _bad_frames(session)
        if live.stopped and live.state in ("done", "idle", "fault"):
            return False
        if live.stopped and not frames and now - last_data_wall > 0.3:
            # stopped event seen and the status frame that follows it waited for: end
            return False
        if not live.stopped and not frames and now - last_data_wall > 0.3 and _stop_evident(live):
            # the stopped event was lost, but the status frames or the profile's end show the stop
            live.stopped = True
            live.stop_reason = "profile end" if live.t_s >= live.total_s else "stopped (event lost)"
            rec.event(
                live.t_s,
                "host",
                0,
                0,
                f"the device went quiet in state {live.state} at "
                f"{live.t_s:.3f} s; its stopped event did not arrive",
            )
            return False
        if now - last_data_wall > options.device_timeout_s:
            raise DeviceError(
                f"device fell silent for {options.device_timeout_s:.1f} s on "
                f"{session.t.name} while running"
            )
        if observer is not None and now - last_update >= options.on_update_s:
            last_update = now
            observer.update(live)


def _stop_evident(live: LiveState) -> bool:
    """The device's own frames say it was stopping or done (status), or its profile has ended."""
    seen = live.status.get("state") if live.status else None
    return seen in ("stopping", "done", "fault") or (live.total_s > 0 and live.t_s >= live.total_s)


def _bad_frames(session: Session) -> int:
    d = session.decoder
    return d.crc_errors + d.cobs_errors + d.len_errors + d.unknown_id


def _stop_device(
    session: Session, rec: Recorder, observer: Observer, sig: _Interrupts, reason: str = ""
) -> None:
    """A signal (or `reason`: a host failure): ask for a controlled stop, keep logging until the
    device reports it; a second signal, or 5 s without the stop, sends abort."""
    live = rec.live
    why = sig.signal_name or "SIGINT"
    if reason:
        observer.message(f"{reason}: stopping the motor (Ctrl-C to abort)")
    else:
        rec.event(live.t_s, "host", 0, 0, f"interrupted by {why}: stop sent")
        by = "" if why == "SIGINT" else f" by {why}"  # a kill (SIGTERM), a closed terminal
        observer.message(f"interrupted{by}: stopping the motor (Ctrl-C again to abort)")
    first = sig.count
    try:
        session.send("stop")
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and not live.stopped:
            if sig.count > max(first, 1):
                session.send("abort")
                rec.event(live.t_s, "host", 0, 0, "interrupted twice: abort sent")
                break
            frames = session.poll(0.02)
            rec.frames(frames)
            session.send("heartbeat", counter=0)
        else:
            if not live.stopped:
                session.send("abort")
                rec.event(live.t_s, "host", 0, 0, "device did not stop within 5 s: abort sent")
        # the status frame that follows the stop
        end = time.monotonic() + 0.1
        while time.monotonic() < end:
            rec.frames(session.poll(0.02))
    except KeyboardInterrupt:
        _send_quietly(session, "abort")
        rec.event(live.t_s, "host", 0, 0, "interrupted twice: abort sent")
    except (TransportError, DeviceError) as e:
        rec.event(live.t_s, "host", 0, 0, f"link error while stopping: {e}")


def _upload_capture(session: Session, rec: Recorder, observer: Observer | None) -> int:
    count = int(rec.live.status.get("capture_count", 0) or 0)
    # the status frame may predate the end of the capture: drain what is left, then ask; one
    # that reports the device at rest was sent after its last control period (the firmware
    # sends it at the change of state), so its count is final: nothing to wait for
    at_rest = rec.live.stopped and rec.live.status.get("state") in ("done", "fault", "idle")
    rec.frames(session.poll(0.0 if at_rest else 0.05))
    count = int(rec.live.status.get("capture_count", count) or 0)
    if count <= 0:
        return 0
    if observer is not None:
        observer.message(f"uploading capture ({count} samples)")
    capacity = _identity(session).capture_len
    if count > capacity:  # a device-provided count is checked against what it said at hello
        rec.event(
            rec.live.t_s, "warning", 0, 0, f"capture count {count} is implausible: not uploaded"
        )
        return 0
    try:
        chunks = session.read_capture(count)
    except (DeviceError, TransportError) as e:
        rec.event(rec.live.t_s, "warning", 0, 0, f"capture upload failed: {e}")
        return 0
    missing = session.capture_missing
    if missing:
        rec.event(
            rec.live.t_s,
            "warning",
            0,
            0,
            f"capture: {len(missing)} chunks did not arrive (offsets {missing[:8]}"
            f"{' ...' if len(missing) > 8 else ''})"
            + (
                "; the upload was given up after chunks in a row were lost"
                if session.capture_abandoned
                else ""
            )
            + f"; the {count} samples are kept but for those",
        )
    rec.frames(session.poll(0.0))
    return rec.capture(chunks)


def _write_link_stats(writer: LogWriter, session: Session, rec: Recorder) -> None:
    d = session.decoder
    live = rec.live
    writer.write(
        "/host/link",
        live.t_s,
        {
            "wall_s": live.wall_s,
            "frames_ok": d.frames_ok,
            "crc_errors": d.crc_errors,
            "cobs_errors": d.cobs_errors,
            "len_errors": d.len_errors,
            "unknown_id": d.unknown_id,
            "octets": d.octets,
            "seq_gaps": live.seq_gaps,
        },
    )
