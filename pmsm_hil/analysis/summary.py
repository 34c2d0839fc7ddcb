"""Per-segment run summary: speed error after settling, recovery after load steps, current ripple,
faults. Everything is derived from the log alone (segment boundaries from the segment_start events),
so it works on any pmsm-hil log.

Definitions (docs/analysis.md):
- band: max(1 % of |setpoint|, 1 r/min), the speed-tracking bound.
- plateau window: from the end of the segment's ramp plus min(0.5 s, half the plateau) to the
  segment's end; the mean speed error is taken there.
- recovery (segments whose load differs from the previous segment's, at a constant speed
  reference): time from the segment start
  to the moment after which the 20 ms moving average of the speed error stays within the band.
- ripple: RMS of i_d − i_d* and i_q − i_q* in the plateau window (telemetry rate).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.analysis.true_speed import true_speed_correction_rpm
from pmsm_hil.log.reader import Log, read_log

if TYPE_CHECKING:
    from pmsm_hil.log.reader import Log

RECOVERY_LIMIT_S = 0.3
AVG_WINDOW_S = 0.02
# a segment that reaches its set-point less than this before its end has no plateau: its mean
# error (over the last instants of a ramp) is shown but not judged
MIN_PLATEAU_S = 0.1


@dataclass
class SegmentStats:
    index: int
    name: str
    t_start_s: float
    t_end_s: float
    setpoint_rpm: float
    load_nm: float
    load_step_nm: float
    band_rpm: float
    # the figures of the plateau window; the defaults are a segment too short to measure
    mean_error_rpm: float = float("nan")
    mean_ok: bool = True
    # the plant's own speed (emulator logs only): mean_error_rpm plus the measured speed's mean
    # error at the truth's instants in the window
    true_mean_error_rpm: float | None = None
    recovery_s: float | None = None  # None: no load step in this segment
    recovery_ok: bool | None = None
    ripple_d_a: float = float("nan")
    ripple_q_a: float = float("nan")
    faults: int = 0
    plateau_s: float = float("inf")  # time at the final set-point before the segment's end
    mean_judged: bool = True  # False: no plateau (plateau_s < MIN_PLATEAU_S), mean_ok then True


@dataclass
class RunSummary:
    path: str
    segments: list[SegmentStats] = field(default_factory=list)
    faults: list[str] = field(default_factory=list)
    duration_s: float = 0.0
    frames: int = 0
    # completeness: what the log holds against what the run was to play
    expected: list[str] = field(default_factory=list)  # the profile's segment names (metadata)
    missing: list[int] = field(default_factory=list)  # segments the log never shows starting
    partial: list[int] = field(default_factory=list)  # segments the log shows cut short
    ended: str = ""  # "profile end", "stopped: REASON", or "" (the log just ends)
    problems: list[str] = field(default_factory=list)  # truncated file, no summary section, ...
    estimator: dict | None = None  # the angle estimator closing the loop (estimator_stats)
    run: str = ""  # what ran: profile, rig, seed (from the log's metadata; "" when not there)

    @property
    def complete(self) -> bool:
        return (
            self.ended == "profile end"
            and not self.missing
            and not self.partial
            and not self.problems
        )

    @property
    def ok(self) -> bool:
        return (
            self.complete
            and not self.faults
            and all(s.mean_ok and s.recovery_ok is not False for s in self.segments)
        )

    def as_dict(self) -> dict:
        return {
            "path": self.path,
            "run": self.run,
            "ok": self.ok,
            "complete": self.complete,
            "ended": self.ended,
            "duration_s": self.duration_s,
            "faults": self.faults,
            "missing": self.missing,
            "partial": self.partial,
            "problems": self.problems,
            "segments": [asdict(s) for s in self.segments],
            "estimator": self.estimator,
        }


def _moving_average(x: np.ndarray, n: int) -> np.ndarray:
    if n <= 1 or len(x) < n:
        return x.copy()
    c = np.cumsum(np.insert(x, 0, 0.0))
    out = np.empty_like(x)
    out[n - 1 :] = (c[n:] - c[:-n]) / n
    out[: n - 1] = c[1:n] / np.arange(1, n)
    return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def recovery_time(t: np.ndarray, err: np.ndarray, band: float, t0: float) -> float:
    """Time from t0 until the moving-average error stays within band; inf if it never does."""
    if len(t) < 2:
        return float("inf")
    dt = float(np.median(np.diff(t)))
    avg = _moving_average(err, max(1, round(AVG_WINDOW_S / dt)))
    outside = np.nonzero(np.abs(avg) > band)[0]
    if len(outside) == 0:
        return 0.0
    last = outside[-1]
    if last + 1 >= len(t):
        return float("inf")
    return float(t[last + 1] - t0)


def summarize(
    tel: dict,
    events: dict,
    names: list[str] | None = None,
    path: str = "",
    truth: dict | None = None,
    pole_pairs: int = 0,
) -> RunSummary:
    """``pole_pairs``: the motor's (the log's motor file), for the plant's mean speed from the
    truth's angle (analysis.true_speed); 0: from the truth's speed samples."""
    t = np.asarray(tel["t_s"], dtype=float)
    ref = np.asarray(tel["speed_ref_rpm"], dtype=float)
    spd = np.asarray(tel["speed_rpm"], dtype=float)
    load = np.asarray(tel["load_nm"], dtype=float)
    # the current errors are taken per segment window, not as whole-log difference arrays (on a
    # one-hour log 0.4 s of the summary alone, most of it the first touch of fresh pages)
    i_d, i_d_ref = np.asarray(tel["i_d_a"], float), np.asarray(tel["i_d_ref_a"], float)
    i_q, i_q_ref = np.asarray(tel["i_q_a"], float), np.asarray(tel["i_q_ref_a"], float)
    kinds = [str(k) for k in events.get("kind", [])]
    ev_t = np.asarray(events.get("t_s", []), dtype=float)
    ev_arg = np.asarray(events.get("arg", []), dtype=int)
    starts = [(float(ev_t[i]), int(ev_arg[i])) for i, k in enumerate(kinds) if k == "segment_start"]
    texts = [str(x) for x in events.get("text", [])]
    # the run's end: the profile's end, a stop, or the moment the host asked for one (a partial
    # segment is judged up to there, not through the quick stop that follows)
    ends = [
        float(ev_t[i])
        for i, k in enumerate(kinds)
        if k in ("profile_done", "stopped", "heartbeat_lost")
        or (k == "host" and texts[i].startswith(("interrupted", "stop requested")))
    ]
    fault_events = [
        (float(ev_t[i]), str(events["text"][i]))
        for i, k in enumerate(kinds)
        if k in ("fault", "heartbeat_lost")
    ]
    summary = RunSummary(
        path=path,
        duration_s=float(t[-1]) if len(t) else 0.0,
        frames=len(t),
        faults=[f"{ts:.3f} s {txt}" for ts, txt in fault_events],
        expected=list(names or []),
    )
    done = [i for i, k in enumerate(kinds) if k == "profile_done"]
    stops = [i for i, k in enumerate(kinds) if k == "stopped"]
    if done:
        summary.ended = "profile end"
    elif stops:
        text = str(events["text"][stops[0]])
        summary.ended = text if text.startswith("stopped") else f"stopped: {text}"
    seen = {idx for _, idx in starts}
    if names:
        summary.missing = [i for i in range(len(names)) if i not in seen]
        if not done and starts:
            summary.partial = [starts[-1][1]]
    prev_load = 0.0
    for k, (t0, idx) in enumerate(starts):
        t1 = (
            starts[k + 1][0] if k + 1 < len(starts) else (min(ends) if ends else summary.duration_s)
        )
        sel = (t >= t0) & (t < t1)
        last = k + 1 == len(starts)  # the last segment seen holds the faults that ended the run
        n_faults = sum(1 for ft, _ in fault_events if t0 <= ft and (ft < t1 or last))
        name = names[idx] if names and idx < len(names) else f"segment {idx}"
        if sel.sum() < 4:  # too short to measure (a blip): listed, not judged
            setpoint = float(np.interp(t0, t, ref)) if len(t) else float("nan")
            seg_load = float(np.median(load[sel])) if sel.any() else prev_load
            summary.segments.append(
                SegmentStats(
                    idx,
                    name,
                    t0,
                    t1,
                    setpoint,
                    seg_load,
                    seg_load - prev_load,
                    max(0.01 * abs(setpoint), 1.0),
                    faults=n_faults,
                    plateau_s=0.0,
                    mean_judged=False,
                )
            )
            prev_load = seg_load
            continue
        ts, r, s = t[sel], ref[sel], spd[sel]
        setpoint = float(r[-1])
        seg_load = float(np.median(load[sel]))
        band = max(0.01 * abs(setpoint), 1.0)
        at_final = np.nonzero(np.abs(r - setpoint) > 1e-6 + 0.001 * abs(setpoint))[0]
        t_ramp_end = (
            float(ts[at_final[-1] + 1]) if len(at_final) and at_final[-1] + 1 < len(ts) else t0
        )
        plateau = t1 - t_ramp_end
        w0 = t_ramp_end + min(0.5, 0.5 * plateau)
        win = sel & (t >= w0)
        n_win = int(win.sum())
        err = s - r
        mean_err = float(np.mean(spd[win] - ref[win])) if n_win else float("nan")
        judged = plateau > MIN_PLATEAU_S - 1e-6
        true_err = None
        if truth is not None and len(truth.get("t_s", [])) and n_win:
            # the plant's own speed error: the mean error corrected by the speed measurement's
            # mean error, from the truth's angle travelled (analysis.true_speed); without the
            # truth's angle or the pole pairs, from the truth's speed at its instants (biased by
            # a ripple at a multiple of truth_hz)
            tt = np.asarray(truth["t_s"], float)
            tw = (tt >= w0) & (tt < t1)
            corr = None
            if pole_pairs and "theta_e_rad" in truth and tw.sum() >= 2:
                tsel = np.flatnonzero(tw)
                corr = true_speed_correction_rpm(
                    t[win], spd[win], tt[tsel], np.asarray(truth["theta_e_rad"])[tsel], pole_pairs
                )
                if corr is not None:  # against the measured mean over the truth's span
                    span = win & (t >= tt[tsel[0]]) & (t <= tt[tsel[-1]])
                    corr += float(np.mean(spd[span] - ref[span])) - mean_err if span.any() else 0
            if corr is not None:
                true_err = mean_err + corr
            elif tw.sum():
                meas = np.interp(tt[tw], t, spd)
                true_err = mean_err + float(
                    np.mean(np.asarray(truth["speed_rpm"], float)[tw] - meas)
                )
        step = seg_load - prev_load
        rec = rec_ok = None
        ramped = abs(float(r[0]) - setpoint) > 1e-6 + 0.001 * abs(setpoint)
        if abs(step) > 1e-6 and not ramped:  # a load step on a plateau (not during a ramp)
            rec = recovery_time(ts, err, band, t0)
            rec_ok = rec <= RECOVERY_LIMIT_S
        summary.segments.append(
            SegmentStats(
                index=idx,
                name=name,
                t_start_s=t0,
                t_end_s=t1,
                setpoint_rpm=setpoint,
                load_nm=seg_load,
                load_step_nm=step,
                band_rpm=band,
                mean_error_rpm=mean_err,
                mean_ok=bool(abs(mean_err) <= band) or not judged,
                true_mean_error_rpm=true_err,
                recovery_s=rec,
                recovery_ok=rec_ok,
                ripple_d_a=_rms(i_d[win] - i_d_ref[win]) if n_win else float("nan"),
                ripple_q_a=_rms(i_q[win] - i_q_ref[win]) if n_win else float("nan"),
                faults=n_faults,
                plateau_s=plateau,
                mean_judged=judged,
            )
        )
        prev_load = seg_load
    return summary


def log_problems(log: Log) -> list[str]:
    """What is wrong with the file itself: truncation, a missing summary section, no data."""
    out = []
    total = sum(log.counts.values())
    if log.truncated:
        out.append(f"the file ends inside a record (truncated); {total} messages recovered")
    elif not log.finalised:
        out.append(
            f"the file has no summary section (the writer did not finish); {total} messages "
            f"recovered"
        )
    out += [str(p) for p in log.problems]
    status = log.topic("/pmsm/status") if "/pmsm/status" in log.topics else {}
    dropped = int(np.max(status["tx_dropped"])) if len(status.get("tx_dropped", [])) else 0
    if dropped:
        out.append(f"the device dropped {dropped} telemetry frames (the link could not carry them)")
    rx_bad = int(np.max(status["rx_bad"])) if len(status.get("rx_bad", [])) else 0
    if rx_bad:
        out.append(
            f"the device rejected {rx_bad} received frames (corrupted, incomplete or spliced, or "
            "on a shared CAN bus another node's on its identifiers)"
        )
    link = log.topic("/host/link") if "/host/link" in log.topics else {}

    def last(key: str) -> int:  # the counters are running totals: the last row holds the run's
        v = link.get(key)
        return int(np.max(v)) if v is not None and len(v) else 0

    gaps = last("seq_gaps")
    crc = last("crc_errors")
    bad = crc + last("cobs_errors") + last("len_errors")
    unknown = last("unknown_id")
    if gaps or bad or unknown:
        out.append(
            f"the host lost frames on the link: {gaps} sequence gaps, {bad} corrupted frames "
            f"rejected ({crc} failed their CRC)"
            + (f", {unknown} frames of an identifier it does not know" if unknown else "")
        )
    return out


# what the summary reads of a log (read_log(path, topics=...)): nothing else is decoded
SUMMARY_TOPICS = {
    "/pmsm/telemetry": (
        "t_s",
        "speed_ref_rpm",
        "speed_rpm",
        "load_nm",
        "i_d_a",
        "i_d_ref_a",
        "i_q_a",
        "i_q_ref_a",
    ),
    "/pmsm/events": None,
    "/sim/truth": ("t_s", "speed_rpm", "theta_e_rad"),
    "/pmsm/status": ("t_s", "tx_dropped", "rx_bad"),
    "/host/link": ("t_s", "seq_gaps", "crc_errors", "cobs_errors", "len_errors", "unknown_id"),
}


def summarize_log(path: Path, log: Log | None = None) -> RunSummary:
    """The summary of a log file (or of ``log``, the file already read with at least
    SUMMARY_TOPICS); raises LogFormatError (not MCAP) or ValueError (empty file)."""
    if Path(path).stat().st_size == 0:
        raise ValueError(f"{path}: the file is empty (0 octets): no run was recorded")
    log = log if log is not None else read_log(path, topics=SUMMARY_TOPICS)
    names = None
    meta = log.metadata.get("run", {})
    if meta.get("segment_names"):
        names = meta["segment_names"].split("|")
    truth = log.topic("/sim/truth") if "/sim/truth" in log.topics else None
    summary = summarize(
        log.topic("/pmsm/telemetry"),
        log.topic("/pmsm/events"),
        names,
        str(path),
        truth,
        _pole_pairs(log) if truth is not None else 0,
    )
    summary.problems = log_problems(log)
    summary.run = run_tag(log.metadata)
    if "/pmsm/estimator" in log.topics:
        summary.estimator = estimator_stats(log.topic("/pmsm/estimator"))
    return summary


def _pole_pairs(log: Log) -> int:
    """The pole pairs of the log's motor file (its attachment), 0 when it does not say."""
    import yaml

    att = log.attachment("motor.yaml")
    try:
        data = yaml.safe_load(att.text) if att is not None else None
        return int(data.get("pole_pairs", 0)) if isinstance(data, dict) else 0
    except (yaml.YAMLError, TypeError, ValueError):
        return 0


def rig_name(meta: dict) -> str:
    """The rig a log's run was on, by name, from its metadata ("" when none is named)."""
    rig = meta.get("run", {}).get("rig", "")
    if rig:
        return Path(rig).stem
    return meta.get("rig_effects", {}).get("rig", "")


def control_tag(run: dict) -> str:
    """The current controllers and the angle source of a run, from its metadata: "MPCC", "FOC",
    "MPCC then FOC" (in the order the segments first run them), with ", sensorless (mras)" when
    an estimator gave the angle; "" for a log written before they were recorded."""
    seen: list[str] = []
    for c in str(run.get("current_ctrl", "")).split("|"):
        if c and c.upper() not in seen:
            seen.append(c.upper())
    tag = " then ".join(seen)
    src = run.get("angle_src", "")
    if tag and src and src != "encoder":
        tag += f", sensorless ({src})"
    return tag


def run_tag(meta: dict) -> str:
    """What ran, from a log's metadata: "profile paper-a, MPCC, motor paper-a-ipmsm, rig
    lab-typical, seed 4" (a rig's run,
    which has no seed, names its board)."""
    run = meta.get("run", {})
    rig = rig_name(meta)
    parts = [f"profile {run['profile']}"] if run.get("profile") else []
    ctrl = control_tag(run)
    if ctrl:
        parts.append(ctrl)
    if run.get("motor"):  # two runs with other motor files (a commissioned one) tell apart
        parts.append(f"motor {run['motor']}")
    if rig:
        parts.append(f"rig {rig}")
    if run.get("seed"):
        parts.append(f"seed {run['seed']}")
    elif meta.get("device", {}).get("board"):
        parts.append(f"board {meta['device']['board']}")
    return ", ".join(parts)


def estimator_stats(est: dict) -> dict | None:
    """The angle estimator's figures over its frames while it closed the loop: its name, the
    angle error against the encoder (mean, RMS, largest), and where it was out of lock."""
    in_loop = np.asarray(est["in_loop"], bool)
    if not len(in_loop):
        return None
    t = np.asarray(est["t_s"], float)
    err = np.asarray(est["theta_err_rad"], float)[in_loop]
    unlocked = t[in_loop & ~np.asarray(est["locked"], bool)]
    return {
        "estimator": ", ".join(sorted(set(est["estimator"]))),
        "in_loop_s": float(np.sum(in_loop) * np.median(np.diff(t))) if len(t) > 1 else 0.0,
        "theta_err_mean_rad": float(err.mean()) if err.size else None,
        "theta_err_rms_rad": float(np.sqrt(np.mean(err**2))) if err.size else None,
        "theta_err_max_rad": float(np.max(np.abs(err))) if err.size else None,
        "unlocked_frames": int(unlocked.size),
        "first_unlocked_s": float(unlocked[0]) if unlocked.size else None,
    }
