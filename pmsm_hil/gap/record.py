"""The gap diagnosis's data: a control-rate record (one row per control period) or a steady-state
dq record, loaded from an MCAP log (docs/gap.md, "Data").

Sources, in order of preference:
- `/pmsm/control_rate`: a continuous control-rate recording (the emulator's, simulation only, or an
  imported CSV);
- `/pmsm/capture`: the firmware's triggered captures (bursts of 1/Ts samples);
- `/pmsm/steady_dq`: imported steady-state dq data.

Sample k holds the phase currents measured at t_k and the voltage applied over [t_k, t_k+1]:
switch states `s_abc` (held over the period), duties `d_abc`, or `u_alpha_v u_beta_v`.
"""

from __future__ import annotations

import contextlib
import itertools
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from pmsm_hil.log.schemas import FieldDef, TopicDef

if TYPE_CHECKING:
    from pmsm_hil.log.reader import Log

CONTROL_TOPIC = "/pmsm/control_rate"
STEADY_TOPIC = "/pmsm/steady_dq"


def _f(name: str, unit: str, doc: str) -> FieldDef:
    return FieldDef(name, "float64", unit, doc)


CONTROL_FIELDS = (
    _f("t_s", "s", "time of the sample (start of the period)"),
    _f("i_a_a", "A", "phase a current as measured"),
    _f("i_b_a", "A", "phase b current as measured"),
    _f("i_c_a", "A", "phase c current as measured (NaN: not measured)"),
    _f("s_a", "", "switch state of leg a held over the period (NaN: not given)"),
    _f("s_b", "", "switch state of leg b"),
    _f("s_c", "", "switch state of leg c"),
    _f("d_a", "", "duty of leg a over the period (NaN: not given)"),
    _f("d_b", "", "duty of leg b"),
    _f("d_c", "", "duty of leg c"),
    _f("u_alpha_v", "V", "applied alpha voltage (NaN: not given)"),
    _f("u_beta_v", "V", "applied beta voltage"),
    _f("pwm_on", "", "1: the inverter switches; 0: all switches off (NaN: unknown, taken as on)"),
    _f("v_dc_v", "V", "DC-link voltage"),
    _f("theta_e_rad", "rad", "electrical rotor angle"),
    _f("omega_e_rad_s", "rad/s", "electrical speed (NaN: from the angle)"),
    _f("load_nm", "N m", "load torque (NaN: unknown)"),
    _f("temp_winding_c", "degC", "winding temperature (NaN: unknown)"),
    _f("temp_magnet_c", "degC", "magnet temperature (NaN: unknown)"),
)
CONTROL_TOPICDEF = TopicDef(
    CONTROL_TOPIC,
    "pmsm_hil/msg/ControlRate",
    CONTROL_FIELDS,
    rate="1/ts_s, continuous",
    doc="Control-rate record for the gap diagnosis.",
)

STEADY_FIELDS = (
    _f("t_s", "s", "time"),
    _f("u_d_v", "V", "d-axis voltage"),
    _f("u_q_v", "V", "q-axis voltage"),
    _f("i_d_a", "A", "d-axis current"),
    _f("i_q_a", "A", "q-axis current"),
    _f("omega_e_rad_s", "rad/s", "electrical speed"),
    _f("torque_nm", "N m", "shaft torque (NaN: unknown)"),
    _f("temp_winding_c", "degC", "winding temperature (NaN: unknown)"),
    _f("temp_magnet_c", "degC", "magnet temperature (NaN: unknown)"),
)
STEADY_TOPICDEF = TopicDef(
    STEADY_TOPIC,
    "pmsm_hil/msg/SteadyDq",
    STEADY_FIELDS,
    rate="as recorded",
    doc="Steady-state dq operating points.",
)

GAP_TOPICS = (CONTROL_TOPICDEF, STEADY_TOPICDEF)


class RecordError(ValueError):
    """The log holds no usable data for the diagnosis (the message says why)."""


@dataclass
class ControlRecord:
    """Control-rate data, one row per period. ``runs`` are the index ranges [a, b) of contiguous
    sampling (a triggered capture gives one run per burst)."""

    t_s: np.ndarray
    i_abc: np.ndarray  # (N, 3) A; column 2 NaN when not measured
    voltage_kind: str  # "switch", "duty" or "alphabeta"
    v_cmd: np.ndarray  # (N, 3) switch states or duties, or (N, 2) u_alpha, u_beta
    pwm_on: np.ndarray  # (N,) bool
    v_dc_v: np.ndarray
    theta_e_rad: np.ndarray
    omega_e_rad_s: np.ndarray
    ts_s: float
    runs: list[tuple[int, int]]
    load_nm: np.ndarray | None = None
    temp_winding_c: np.ndarray | None = None
    temp_magnet_c: np.ndarray | None = None
    source: str = ""
    sensor_spec: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # what the reader of the diagnosis must know
    # counts per turn of an incremental encoder read at the start of each count (pmsm-hil's
    # firmware): its angle lags the rotor by half a count on average, which the diagnosis takes
    # out (ControlRecord.angle_lag_e_rad); 0: not known (a CSV import) or not an encoder's angle
    angle_counts: int = 0

    def angle_lag_e_rad(self, pole_pairs: int) -> float:
        """The recorded angle's mean lag behind the rotor (electrical rad): half a count."""
        return float(np.pi * pole_pairs / self.angle_counts) if self.angle_counts > 0 else 0.0

    @property
    def n(self) -> int:
        return len(self.t_s)

    def pairs(self) -> np.ndarray:
        """Indices k with k+1 in the same run (the one-step transitions)."""
        out = [np.arange(a, b - 1) for a, b in self.runs if b - a >= 2]
        return np.concatenate(out) if out else np.empty(0, dtype=np.int64)

    def u_alpha_beta(self) -> np.ndarray:
        """The nominal applied stator voltage (N, 2), V: ideal inverter."""
        if self.voltage_kind == "alphabeta":
            return np.asarray(self.v_cmd, float)
        v = self.v_cmd * self.v_dc_v[:, None]
        u = np.stack(
            [(2 * v[:, 0] - v[:, 1] - v[:, 2]) / 3.0, (v[:, 1] - v[:, 2]) / np.sqrt(3.0)], axis=1
        )
        u[~self.pwm_on] = 0.0
        return u


@dataclass
class SteadyRecord:
    t_s: np.ndarray
    u_dq: np.ndarray
    i_dq: np.ndarray
    omega_e_rad_s: np.ndarray
    torque_nm: np.ndarray | None = None
    temp_winding_c: np.ndarray | None = None
    source: str = ""
    notes: list[str] = field(default_factory=list)


def split_runs(t_s: np.ndarray, ts_s: float, tol: float = 0.25) -> list[tuple[int, int]]:
    """Contiguous runs: a step other than ts_s (within tol·ts_s) starts a new run."""
    if len(t_s) == 0:
        return []
    dt = np.diff(t_s)
    brk = np.nonzero(np.abs(dt - ts_s) > tol * ts_s)[0] + 1
    edges = np.concatenate([[0], brk, [len(t_s)]])
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]


def _opt(cols: dict, name: str) -> np.ndarray | None:
    v = cols.get(name)
    if v is None:
        return None
    v = np.asarray(v, float)
    return None if np.all(np.isnan(v)) else v


def _omega_from_theta(theta: np.ndarray, runs, ts_s: float, half_window: int = 10) -> np.ndarray:
    """Electrical speed from the angle: central difference over +-half_window samples (an encoder's
    counts make the one-period difference coarse)."""
    w = np.zeros_like(theta)
    for a, b in runs:
        if b - a < 2:
            continue
        u = np.unwrap(theta[a:b])
        n = b - a
        i = np.arange(n)
        lo, hi = np.maximum(i - half_window, 0), np.minimum(i + half_window, n - 1)
        w[a:b] = (u[hi] - u[lo]) / ((hi - lo) * ts_s)
    return w


def speed_from_angle(
    theta: np.ndarray, omega: np.ndarray, runs: list[tuple[int, int]], ts_s: float, sg_n: int = 41
) -> np.ndarray:
    """The recorded electrical speed made consistent with the recorded angle, zero-phase: omega plus
    the derivative (quadratic Savitzky-Golay over sg_n samples) of the angle's departure from
    omega's integral (held over each period). A recorded speed is often an observer's or a filter's
    output that lags the angle during ramps (docs/gap.md, "The torque balance"); a speed that
    agrees with the angle (steps included) is kept as it is, and the angle's quantisation is
    smoothed away."""
    from scipy.signal import savgol_filter

    w = np.array(omega, float)
    for a, b in runs:
        if b - a < sg_n:
            continue
        phi = np.concatenate([[0.0], np.cumsum(w[a : b - 1]) * ts_s])
        dev = np.unwrap(theta[a:b]) - theta[a] - phi
        w[a:b] += savgol_filter(dev, sg_n, 2, deriv=1, delta=ts_s)
    return w


def record_from_columns(
    cols: dict[str, np.ndarray],
    ts_s: float | None = None,
    source: str = "",
    sensor_spec: dict | None = None,
) -> ControlRecord:
    """A ControlRecord from columns named as CONTROL_FIELDS (missing optional ones may be absent)."""
    t = np.asarray(cols["t_s"], float)
    if len(t) < 3:
        raise RecordError(f"{source}: fewer than 3 control-rate samples")
    order = np.argsort(t, kind="stable")
    cols = {k: np.asarray(v)[order] for k, v in cols.items()}
    t = t[order]
    if ts_s is None:
        ts_s = float(np.median(np.diff(t)))
    runs = split_runs(t, ts_s)
    n = len(t)
    nan = np.full(n, np.nan)
    ia, ib = np.asarray(cols["i_a_a"], float), np.asarray(cols["i_b_a"], float)
    ic = np.asarray(cols.get("i_c_a", nan), float)
    s = [np.asarray(cols.get(k, nan), float) for k in ("s_a", "s_b", "s_c")]
    d = [np.asarray(cols.get(k, nan), float) for k in ("d_a", "d_b", "d_c")]
    u = [np.asarray(cols.get(k, nan), float) for k in ("u_alpha_v", "u_beta_v")]
    if not np.any(np.isnan(np.stack(s))):
        kind, v_cmd = "switch", np.stack(s, axis=1)
    elif not np.any(np.isnan(np.stack(d))):
        kind, v_cmd = "duty", np.stack(d, axis=1)
    elif not np.any(np.isnan(np.stack(u))):
        kind, v_cmd = "alphabeta", np.stack(u, axis=1)
    else:
        raise RecordError(
            f"{source}: no complete applied voltage (s_a s_b s_c, d_a d_b d_c or u_alpha_v u_beta_v)"
        )
    pw = np.asarray(cols.get("pwm_on", nan), float)
    pwm_on = np.where(np.isnan(pw), True, pw > 0.5)
    theta = np.mod(np.asarray(cols["theta_e_rad"], float), 2 * np.pi)
    om = _opt(cols, "omega_e_rad_s")
    if om is None:
        om = _omega_from_theta(theta, runs, ts_s)
    vdc = np.asarray(cols.get("v_dc_v", nan), float)
    if kind != "alphabeta" and np.any(np.isnan(vdc)):
        raise RecordError(f"{source}: v_dc_v is needed with switch states or duties")
    return ControlRecord(
        t_s=t,
        i_abc=np.stack([ia, ib, ic], axis=1),
        voltage_kind=kind,
        v_cmd=v_cmd,
        pwm_on=pwm_on,
        v_dc_v=vdc,
        theta_e_rad=theta,
        omega_e_rad_s=om,
        ts_s=float(ts_s),
        runs=runs,
        load_nm=_opt(cols, "load_nm"),
        temp_winding_c=_opt(cols, "temp_winding_c"),
        temp_magnet_c=_opt(cols, "temp_magnet_c"),
        source=source,
        sensor_spec=dict(sensor_spec or {}),
    )


def sensor_spec_from_metadata(meta: dict[str, dict[str, str]]) -> dict[str, float]:
    """The current-sensor specification a log carries: the `gap_sensors` record (i_noise_a,
    adc_lsb_a, encoder_lines, and encoder_count_start = 1 for an angle read as the start of each
    count) or, from a rig's metadata, only its sensor entries (the diagnosis does
    not read the rig's other effects)."""
    out: dict[str, float] = {}
    src = meta.get("gap_sensors") or {}
    for k in ("i_noise_a", "adc_lsb_a", "encoder_lines", "encoder_count_start"):
        if k in src and src[k] not in ("", "nan"):
            out[k] = float(src[k])
    rig = meta.get("rig") or meta.get("rig_effects") or {}
    pairs = {
        "i_noise_a": "adc_noise.i_noise_a",
        "adc_lsb_a": "adc_quantisation.adc_lsb_a",
        "encoder_lines": "encoder.lines",
    }
    for k, rk in pairs.items():
        if k not in out and rk in rig:
            with contextlib.suppress(ValueError):
                out[k] = float(rig[rk])
    return out


def load_record(path: str | os.PathLike) -> ControlRecord | SteadyRecord:
    """The diagnosis's data from an MCAP log (see the module doc); raises RecordError."""
    from pmsm_hil.log.reader import read_log

    return record_from_log(read_log(path), path)


def _run_control(log: Log) -> dict[str, Any]:
    """The `control` section of the profile the log's run played (its attachment), with the
    current control of each segment; empty for a log without one (a CSV import, a rig's own)."""
    att = log.attachment("profile.yaml")
    if att is None:
        return {}
    try:
        data = yaml.safe_load(att.data.decode("utf-8", "replace")) or {}
    except yaml.YAMLError:
        return {}
    control = dict(data.get("control") or {}) if isinstance(data, dict) else {}
    segs = data.get("segments") if isinstance(data, dict) else None
    control["segment_ctrls"] = [
        s.get("current_ctrl") for s in (segs or []) if isinstance(s, dict) and s.get("current_ctrl")
    ]
    return control


def foc_throughout(run_ctrl: str | None, segment_ctrls: Iterable[str | None]) -> bool:
    """Whether a profile's current control is the PWM modulator (FOC/SVPWM) in every segment:
    the run's `control.current_ctrl` (default mpcc) unless a segment names its own."""
    return {run_ctrl or "mpcc", *(c for c in segment_ctrls if c)} == {"foc"}


def _modulator_problem(
    log: Log, path: str | os.PathLike, rec: ControlRecord, control: dict | None = None
) -> str | None:
    """A record whose voltage is switch states sampled once a period, of a run whose current
    control was a modulator (FOC/SVPWM) throughout: the states are not the voltage applied over
    the period, and a diagnosis on them is meaningless. ``control``: _run_control(log), if read."""
    control = _run_control(log) if control is None else control
    if rec.voltage_kind != "switch" or not foc_throughout(
        control.get("current_ctrl"), control.get("segment_ctrls", [])
    ):
        return None
    return (
        f"{path}: the run used current_ctrl: foc (a PWM modulator) and the record holds switch "
        "states once a period, not the duties or the voltage applied over it: the diagnosis "
        "would take a wrong voltage for every period. Diagnose an FCS-MPCC run "
        "(current_ctrl: mpcc, e.g. the shipped `diagnose` profile), or a record with duties "
        "(d_a, d_b, d_c) or u_alpha_v, u_beta_v (docs/gap.md)"
    )


ENCODER_LINES_DEFAULT = 2500  # the firmware's encoder when the rig names none (docs/profiles.md)


def _firmware_angle_counts(log: Log, control: dict, spec: dict[str, float]) -> int:
    """Counts per turn of the encoder whose count pmsm-hil's firmware read for the recorded angle
    (4 x lines: the rig file's `encoder` effect, else the default 2500 lines), or 0 when the log
    is not one of its runs (no device record) or the angle came from an estimator."""
    if spec.get("encoder_count_start") and spec.get("encoder_lines"):
        # the sensor specification says so (a sealed record of `gap selftest`: no device record)
        return 4 * int(spec["encoder_lines"])
    if not (log.metadata.get("device") or {}).get("fw_version"):
        return 0
    if (control.get("angle_src") or "encoder") != "encoder":
        return 0
    lines: Any = ENCODER_LINES_DEFAULT
    att = log.attachment("rig.yaml")
    if att is not None:
        try:
            rig = yaml.safe_load(att.data.decode("utf-8", "replace")) or {}
        except yaml.YAMLError:
            rig = {}
        enc = (rig.get("effects") or {}).get("encoder") if isinstance(rig, dict) else None
        if isinstance(enc, dict) and enc.get("enabled", True) is not False:
            lines = enc.get("lines", ENCODER_LINES_DEFAULT)
    try:
        return 4 * int(lines)
    except (TypeError, ValueError):
        return 0


def _log_notes(log: Log, path: str | os.PathLike, control: dict | None = None) -> list[str]:
    control = _run_control(log) if control is None else control
    notes = []
    if log.truncated or not log.finalised:
        notes.append(
            f"{path} is not finalised (the run was killed or the file is cut short): the "
            "diagnosis uses what could be recovered"
        )
    angle = control.get("angle_src") or "encoder"
    if angle != "encoder":
        notes.append(
            f"the run's angle came from its estimator (angle_src: {angle}); the diagnosis takes "
            "the recorded angle as the encoder's, so an estimation error reads as an encoder "
            "offset or a delay"
        )
    return notes


def record_from_log(log: Log, path: str | os.PathLike) -> ControlRecord | SteadyRecord:
    """``load_record`` of a log already read (``path`` names it in the messages)."""
    rec = _record_from_log(log, path)
    control = _run_control(log)  # the profile's attachment, read once
    if isinstance(rec, ControlRecord):
        why = _modulator_problem(log, path, rec, control)
        if why:
            raise RecordError(why)
        rec.angle_counts = _firmware_angle_counts(log, control, rec.sensor_spec)
    rec.notes.extend(_log_notes(log, path, control))
    return rec


def _record_from_log(log: Log, path: str | os.PathLike) -> ControlRecord | SteadyRecord:
    spec = sensor_spec_from_metadata(log.metadata)
    ts = None
    run_meta = log.metadata.get("run") or {}
    if run_meta.get("ts_s"):
        try:
            ts = float(run_meta["ts_s"])
        except ValueError:
            ts = None
    if CONTROL_TOPIC in log.topics:
        cols = log.topic(CONTROL_TOPIC)
        gm = log.metadata.get("gap_source") or {}
        if gm.get("ts_s"):
            ts = float(gm["ts_s"])
        return record_from_columns(cols, ts, source=f"{path}: {CONTROL_TOPIC}", sensor_spec=spec)
    if STEADY_TOPIC in log.topics:
        c = log.topic(STEADY_TOPIC)
        return SteadyRecord(
            t_s=np.asarray(c["t_s"], float),
            u_dq=np.stack([c["u_d_v"], c["u_q_v"]], 1),
            i_dq=np.stack([c["i_d_a"], c["i_q_a"]], 1),
            omega_e_rad_s=np.asarray(c["omega_e_rad_s"]),
            torque_nm=_opt(c, "torque_nm"),
            temp_winding_c=_opt(c, "temp_winding_c"),
            source=f"{path}: {STEADY_TOPIC}",
        )
    if "/pmsm/capture" in log.topics and len(log.topic("/pmsm/capture")["t_s"]):
        c = log.topic("/pmsm/capture")
        cols = {
            k: np.asarray(c[k], float)
            for k in (
                "t_s",
                "i_a_a",
                "i_b_a",
                "i_c_a",
                "s_a",
                "s_b",
                "s_c",
                "v_dc_v",
                "theta_e_rad",
                "omega_e_rad_s",
            )
        }
        return record_from_columns(cols, ts, source=f"{path}: /pmsm/capture", sensor_spec=spec)
    cut = (
        " (the file is cut short: the data may have been in the part that is missing)"
        if log.truncated or not log.finalised
        else ""
    )
    raise RecordError(
        f"{path}: no control-rate data ({CONTROL_TOPIC} or /pmsm/capture) and no "
        f"steady-state data ({STEADY_TOPIC}){cut}"
    )


def load_control_record(path: str | os.PathLike) -> ControlRecord:
    """``load_record`` for a log that must hold control-rate data; raises RecordError otherwise."""
    rec = load_record(path)
    if not isinstance(rec, ControlRecord):
        raise RecordError(f"{path}: steady-state data only, control-rate data needed")
    return rec
