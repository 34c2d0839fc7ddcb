"""Report panels of the fast telemetry: speed, dq currents, dq voltages, estimation error.
Each returns a matplotlib Figure, or a string saying why the panel has nothing to show."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.analysis.report_context import RunContext
from pmsm_hil.analysis.report_style import envelope, figure, legend, segment_markers, time_axis

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

TEL = "/pmsm/telemetry"

# what these panels read of a log (read_log(path, topics=...)): nothing else is decoded; of the
# fast telemetry every field (they draw all of them but load_nm, which the summary reads)
READS = {
    TEL: None,
    "/sim/truth": ("t_s", "speed_rpm"),
    "/pmsm/status": ("t_s", "v_dc_v"),
    "/pmsm/estimator": ("t_s", "estimator", "locked", "in_loop"),
}


def _no_telemetry(ctx: RunContext) -> str | None:
    return None if ctx.has(TEL) else "no /pmsm/telemetry messages in the log"


def speed(ctx: RunContext) -> Figure | str:
    why = _no_telemetry(ctx)
    if why:
        return why
    tel = ctx.topic(TEL)
    fig, (ax,) = figure(ctx, "Speed", 1)
    t = tel["t_s"]
    ax.plot(*envelope(t, tel["speed_rpm"]), lw=0.9, color="C0", label="measured (encoder)")
    if not np.array_equal(tel["speed_est_rpm"], tel["speed_rpm"]):
        ax.plot(
            *envelope(t, tel["speed_est_rpm"]),
            lw=0.8,
            color="C2",
            label="estimated (used by the firmware)",
        )
    ax.plot(*envelope(t, tel["speed_ref_rpm"]), lw=1.2, color="k", ls="--", label="reference")
    if ctx.has("/sim/truth"):
        tr = ctx.topic("/sim/truth")
        ax.plot(
            *envelope(tr["t_s"], tr["speed_rpm"]), lw=0.8, color="C3", ls=":", label="plant (truth)"
        )
    segment_markers(ax, ctx, label=True)
    ax.set_ylabel("speed n (r/min)")
    time_axis(ax)
    legend(ax, title="segment starts: dotted,\nindex above the plot")
    return fig


def currents(ctx: RunContext) -> Figure | str:
    why = _no_telemetry(ctx)
    if why:
        return why
    tel = ctx.topic(TEL)
    t = tel["t_s"]
    fig, axes = figure(ctx, "dq currents", 2)
    for ax, axis in zip(axes, ("d", "q"), strict=False):
        ax.plot(
            *envelope(t, tel[f"i_{axis}_a"]),
            lw=0.6,
            color="C0" if axis == "d" else "C1",
            label=f"i_{axis} measured",
        )
        ax.plot(
            *envelope(t, tel[f"i_{axis}_ref_a"]),
            lw=1.1,
            color="k",
            ls="--",
            label=f"i_{axis}* reference",
        )
        segment_markers(ax, ctx, label=axis == "d")
        ax.set_ylabel(f"i_{axis} (A)")
        legend(ax)
    time_axis(axes[-1])
    return fig


def _mean(t: np.ndarray, x: np.ndarray, window_s: float) -> np.ndarray:
    """Centred moving mean over about window_s (the MPCC applies one switching vector per period;
    telemetry's u_d, u_q are their mean over ten periods, which still scatters by tens of volts).
    The window of ``np.convolve(x, ones(n) / n, "same")``, zeros beyond the ends, by scipy.ndimage's
    running filter (an hour's 7.2 M samples in 0.1 s instead of 0.4 s), a block of BLOCK samples
    at a time."""
    if len(t) < 3:
        return x
    # the median interval of at most some 10^5 pairs spread over the series (an hour's full
    # np.diff would be another 58 MB beside the columns)
    s = max(1, (len(t) - 1) // 100_000)
    n = max(1, round(window_s / float(np.median(t[1::s] - t[:-1:s]))))
    if n <= 1 or len(x) < n:
        return x
    from scipy.ndimage import uniform_filter1d

    # a block at a time, each with n samples of its neighbours' on either side (the whole window
    # of its edge samples): scipy copies the line it filters into buffers of its own, twice the
    # series' size for an hour's 7.2 M samples; the zeros beyond the ends stay the series'
    x = np.asarray(x, float)
    out = np.empty_like(x)
    for a in range(0, len(x), BLOCK):
        b = min(a + BLOCK, len(x))
        lo, hi = max(0, a - n), min(len(x), b + n)
        out[a:b] = uniform_filter1d(x[lo:hi], n, mode="constant", cval=0.0)[a - lo : b - lo]
    return out


# the samples a long series is worked through at a time (2 MB of float64)
BLOCK = 1 << 18


VOLTAGE_MEAN_S = 0.02


def voltages(ctx: RunContext) -> Figure | str:
    why = _no_telemetry(ctx)
    if why:
        return why
    tel = ctx.topic(TEL)
    t = tel["t_s"]
    lim = None
    if ctx.has("/pmsm/status"):
        st = ctx.topic("/pmsm/status")
        v = np.asarray(st["v_dc_v"], float) / np.sqrt(3.0)
        if np.any(np.isfinite(v) & (v > 0)):
            lim = envelope(st["t_s"], v)  # once for both axes; -v has the same envelope, negated
    fig, axes = figure(ctx, "dq voltages (as commanded)", 2)
    for ax, axis, c in zip(axes, ("d", "q"), ("C0", "C1"), strict=False):
        u = np.asarray(tel[f"u_{axis}_v"], float)
        ax.plot(*envelope(t, u), lw=0.4, color=c, alpha=0.25, label=f"u_{axis}, each sample")
        ax.plot(
            *envelope(t, _mean(t, u, VOLTAGE_MEAN_S)),
            lw=1.1,
            color=c,
            label=f"u_{axis}, {VOLTAGE_MEAN_S * 1e3:.0f} ms mean",
        )
        if lim is not None:
            ax.plot(*lim, lw=1.0, color="0.3", ls="--", label="±V_dc/√3 (linear limit)")
            ax.plot(lim[0], -lim[1], lw=1.0, color="0.3", ls="--")
        segment_markers(ax, ctx, label=axis == "d")
        ax.set_ylabel(f"u_{axis} (V)")
        legend(ax)
    time_axis(axes[-1])
    return fig


def _wrap(x: np.ndarray) -> np.ndarray:
    """``x`` (a float array of its own, changed in place) into [-pi, pi]: the nearest turn off,
    2.4x quicker than ``%`` on an hour's samples, a block at a time (no temporary of the
    series' size)."""
    for a in range(0, len(x), BLOCK):
        part = x[a : a + BLOCK]
        part -= (2.0 * np.pi) * np.rint(part / (2.0 * np.pi))
    return x


def estimation_error(ctx: RunContext) -> Figure | str:
    why = _no_telemetry(ctx)
    if why:
        return why
    tel = ctx.topic(TEL)
    t = tel["t_s"]
    # one error series at a time, reduced to what is drawn and said of it before the next one
    # (an hour's is 58 MB); its rms from its square's sum as a dot product (no square's series),
    # its envelope (min and max per slice, which degrees keep) converted rather than the series
    d_theta = _wrap(np.subtract(tel["theta_e_est_rad"], tel["theta_e_rad"], dtype=float))
    theta_moved = bool(np.any(d_theta))
    rms = float(np.sqrt(np.dot(d_theta, d_theta) / len(d_theta))) if len(d_theta) else 0.0
    theta_env = envelope(t, d_theta)
    del d_theta
    d_speed = np.subtract(tel["speed_est_rpm"], tel["speed_rpm"], dtype=float)
    if not theta_moved and not np.any(d_speed):
        return (
            "the firmware used the encoder's angle and speed throughout (no sensorless "
            "estimator ran): the estimation error is zero by construction"
        )
    speed_env = envelope(t, d_speed)
    del d_speed
    name, unlocked = "", []
    if ctx.has("/pmsm/estimator"):
        est = ctx.topic("/pmsm/estimator")
        names = sorted(set(est["estimator"]))
        name = f" - {', '.join(names)}" if names else ""
        te = np.asarray(est["t_s"], float)
        bad = ~np.asarray(est["locked"], bool) & np.asarray(est["in_loop"], bool)
        unlocked = te[bad]
    fig, axes = figure(ctx, f"Angle and speed estimation error (estimate − encoder){name}", 2)
    axes[0].plot(
        theta_env[0],
        np.degrees(theta_env[1]),
        lw=0.6,
        color="C4",
        # in rad too: the summaries and the acceptance criteria (angle_error_rms_max_rad) use rad
        label=f"θe,est − θe\n(RMS {rms:.4f} rad = {np.degrees(rms):.2f}°)",
    )
    axes[0].set_ylabel("angle error (° electrical)")
    axes[1].plot(*speed_env, lw=0.6, color="C2", label="n_est − n")
    axes[1].set_ylabel("speed error (r/min)")
    for i, ax in enumerate(axes):
        ax.axhline(0.0, color="k", lw=0.6)
        if len(unlocked):
            ax.plot(
                unlocked,
                np.zeros(len(unlocked)),
                "|",
                color="C3",
                ms=8,
                label="closing the loop out of lock" if i == 0 else None,
            )
        segment_markers(ax, ctx, label=i == 0)
        _estimator_events(ax, ctx, label=i == 0)
        legend(ax)
    time_axis(axes[-1])
    return fig


# the device's events an estimation error is read against: the start-up polarity test's result
# and the faults (lost_lock, over_speed, ...)
_MARKED = {"polarity": ("C1", "--", "polarity test"), "fault": ("C3", "-", "fault")}


def _estimator_events(ax: Axes, ctx: RunContext, label: bool) -> None:
    """A vertical line at each polarity result and fault, labelled once in the legend."""
    if not ctx.has("/pmsm/events"):
        return
    ev = ctx.topic("/pmsm/events")
    seen: set[str] = set()
    for t, kind in zip(ev["t_s"], ev["kind"], strict=False):
        style = _MARKED.get(str(kind))
        if style is None:
            continue
        color, ls, what = style
        ax.axvline(
            float(t), color=color, ls=ls, lw=0.9, label=what if label and what not in seen else None
        )
        seen.add(what)
