"""Report panel: the control-rate capture (/pmsm/capture): phase currents, the legs' duty (switch
states averaged over DUTY_PERIODS control periods), the DC-link voltage, and the raw switch
states of the first ZOOM_PERIODS periods. The firmware records switch states for the MPCC only
(FOC applies SVPWM duties, which the capture does not hold: its s_a..s_c are 0 there), so the
samples taken while FOC ran are left out of the duty and switch-state axes, and said so."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import yaml

from pmsm_hil.analysis.report_context import RunContext
from pmsm_hil.analysis.report_style import figure, legend
from pmsm_hil.profiles.control_checks import segment_controllers

if TYPE_CHECKING:
    from matplotlib.figure import Figure

CAP = "/pmsm/capture"
DUTY_PERIODS = 20  # 1 ms at 20 kHz
ZOOM_PERIODS = 60  # 3 ms at 20 kHz
LEGS = (("a", "C0"), ("b", "C1"), ("c", "C2"))
# what the panel reads of a log (read_log(path, topics=...))
READS = {CAP: ("t_s", "i_a_a", "i_b_a", "i_c_a", "s_a", "s_b", "s_c", "v_dc_v")}


def _duty(s: np.ndarray, n: int) -> np.ndarray:
    if len(s) < n:
        return s.astype(float)
    return np.convolve(s.astype(float), np.ones(n) / n, mode="same")


FOC_NOTE = "FOC (SVPWM) ran: the capture holds switch states for the MPCC only"


def foc_samples(ctx: RunContext, t_s: np.ndarray) -> np.ndarray:
    """True for the capture samples taken while FOC ran: control.current_ctrl and each segment's
    `current_ctrl` (null: the previous one's) from the log's profile, at the segments' starts."""
    att = ctx.log.attachment("profile.yaml")
    mask = np.zeros(len(t_s), dtype=bool)
    try:
        data = yaml.safe_load(att.data.decode("utf-8", "replace")) if att is not None else None
    except yaml.YAMLError:
        return mask
    if not isinstance(data, dict):
        return mask
    control, segments = data.get("control"), data.get("segments")
    control = control if isinstance(control, dict) else {}
    # without segments: the run's own controller
    per_segment = segment_controllers(control, segments if isinstance(segments, list) else [])
    per_segment = per_segment or segment_controllers(control, [{}])
    mask[:] = per_segment[0] == "foc"
    for s in sorted(ctx.segments, key=lambda s: s.t_start_s):
        if 0 <= s.index < len(per_segment):
            mask[t_s >= s.t_start_s - 1e-9] = per_segment[s.index] == "foc"
    return mask


def trigger_text(ctx: RunContext, span_ms: float) -> str:
    """What the capture shows: from the first `capture_triggered` event (segment index, -1 for
    a fault). The buffer records from the start, so a run without a trigger (no segment flagged
    `capture: true`, no fault) still uploads one: the run's last moments, up to the stop."""
    if ctx.has("/pmsm/events"):
        ev = ctx.topic("/pmsm/events")
        for kind, arg in zip(ev["kind"], ev["arg"], strict=False):
            if str(kind) == "capture_triggered":
                i = int(arg)
                if i < 0:
                    return "triggered by a fault"
                name = {s.index: s.name for s in ctx.segments}.get(i)
                return f"triggered at segment {i}" + (f" {name!r}" if name else "")
    return f"not triggered: the run's last {span_ms:.1f} ms (no segment has capture: true)"


def switching_hz(states: dict[str, np.ndarray], ts_s: float) -> dict[str, float]:
    """Each leg's mean switching frequency over the capture: its upper switch's changes over
    consecutive samples where both are known (not NaN: FOC's left out), half of them a period,
    per second. The MPCC's figure that a fixed-carrier drive states as its PWM frequency."""
    out: dict[str, float] = {}
    for ph, s in states.items():
        known = ~np.isnan(s[:-1]) & ~np.isnan(s[1:])
        n = int(known.sum())
        if n and ts_s > 0:
            out[ph] = float(np.count_nonzero(s[1:][known] != s[:-1][known])) / 2.0 / (n * ts_s)
    return out


def capture(ctx: RunContext) -> Figure | str:
    if not ctx.has(CAP):
        return (
            "no /pmsm/capture samples in the log (the upload failed, or the log ends before it: "
            "a run killed or cut off)"
        )
    cap = ctx.topic(CAP)
    t = np.asarray(cap["t_s"], float)
    t_ms = (t - t[0]) * 1e3
    ts_ms = float(np.median(np.diff(t_ms))) if len(t) > 1 else 0.05
    why = trigger_text(ctx, t_ms[-1] + ts_ms)
    foc = foc_samples(ctx, t)
    if foc.any():
        why += f"; {FOC_NOTE}" + (
            " (its samples are left out of the switch axes)" if not foc.all() else ""
        )
    states = {ph: np.where(foc, np.nan, np.asarray(cap[f"s_{ph}"], float)) for ph, _ in LEGS}
    f_sw = switching_hz(states, ts_ms * 1e-3)
    if f_sw:
        legs = ", ".join(f"{ph} {hz / 1e3:.2f}" for ph, hz in f_sw.items())
        why += f"; MPCC switching frequency per leg (mean over the capture): {legs} kHz"
    fig, axes = figure(
        ctx, f"Capture at the control rate, from t = {t[0]:.4f} s", 4, sharex=False, note=why
    )
    ax = axes[0]
    for ph, c in LEGS:
        ax.plot(t_ms, cap[f"i_{ph}_a"], lw=0.8, color=c, label=f"i_{ph}")
    ax.set_ylabel("phase current (A)")
    legend(ax)
    ax = axes[1]
    for ph, c in LEGS:
        ax.plot(t_ms, _duty(states[ph], DUTY_PERIODS), lw=1.0, color=c, label=f"leg {ph}")
    ax.set_ylabel(f"duty, {DUTY_PERIODS}-period mean")
    ax.set_ylim(-0.05, 1.05)
    legend(ax, title="upper switch on")
    ax = axes[2]
    ax.plot(t_ms, cap["v_dc_v"], lw=0.8, color="C3", label="V_dc")
    ax.set_ylabel("DC-link voltage (V)")
    ax.ticklabel_format(axis="y", useOffset=False)
    legend(ax)
    for ax in axes[:3]:
        ax.set_xlim(t_ms[0], t_ms[-1])
        ax.set_xlabel("time since the capture's first sample (ms)")
    ax = axes[3]
    k = min(len(t_ms), ZOOM_PERIODS)
    for j, (ph, c) in enumerate(LEGS):
        base = 2 * (2 - j)  # leg a on top
        ax.step(
            np.append(t_ms[:k], t_ms[k - 1] + ts_ms),
            np.append(states[ph][:k], states[ph][k - 1]) * 0.8 + base,
            where="post",
            lw=1.0,
            color=c,
            label=f"s_{ph} (leg {ph})",
        )
    ax.set_yticks([0, 0.8, 2, 2.8, 4, 4.8], ["c off", "c on", "b off", "b on", "a off", "a on"])
    ax.set_ylim(-0.4, 5.4)
    ax.set_xlim(t_ms[0], t_ms[k - 1] + ts_ms)
    ax.set_ylabel("switch state\n(upper switch)")
    ax.set_xlabel(f"time since the capture's first sample (ms): the first {k} control periods")
    legend(ax)
    if foc.all():
        for ax in (axes[1], axes[3]):
            ax.text(0.5, 0.5, FOC_NOTE, transform=ax.transAxes, ha="center", va="center")
    return fig
