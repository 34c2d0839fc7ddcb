"""Report panel: identified parameters against the plant's truth, with ±2 % bands and segment
markers (the band is the convergence tolerance of pmsm_hil.analysis.identification)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.analysis.identification import TOL
from pmsm_hil.analysis.report_context import RunContext
from pmsm_hil.analysis.report_style import (
    band,
    envelope,
    figure,
    legend,
    segment_markers,
    time_axis,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

ORDER = ("l_d_h", "l_q_h", "psi_f_wb", "r_s_ohm")
STYLE = {
    "nominal": dict(color="C3", ls=(0, (1, 2)), lw=1.8, zorder=3),
    "rls": dict(color="C0", lw=0.9),
    "adaline": dict(color="C1", lw=0.9),
    "nlms_adaline": dict(color="C2", lw=1.1),
}
SCALE = {
    "l_d_h": (1e3, "mH"),
    "l_q_h": (1e3, "mH"),
    "psi_f_wb": (1e3, "mWb"),
    "r_s_ohm": (1.0, "Ω"),
}
LABEL = {"l_d_h": "L_d", "l_q_h": "L_q", "psi_f_wb": "ψ_f", "r_s_ohm": "R_s"}
# what the panel reads of a log (read_log(path, topics=...))
READS = {"/pmsm/params": ("t_s", "estimator", *ORDER), "/sim/truth": ("t_s", *ORDER)}
ZOOM = 0.25  # y range: the truth ± 25 %, so that the start-up transients do not flatten the rest


def parameters(ctx: RunContext) -> Figure | str:
    if not ctx.has("/pmsm/params"):
        return "no /pmsm/params messages in the log"
    par = ctx.topic("/pmsm/params")
    has_truth = ctx.has("/sim/truth")
    if not has_truth:
        return (
            "no /sim/truth in the log (a rig log): there is no truth to compare the "
            "parameters with; the identification table uses the motor file's values"
        )
    tr = ctx.topic("/sim/truth")
    # the estimator's names as the log's objects (a handful, shared): compared at once, not
    # converted (an hour's 1.44 M rows: 0.35 s to fixed-width strings)
    names = np.asarray(par["estimator"], dtype=object)
    t_all = np.asarray(par["t_s"], float)
    rows = {e: sel for e in STYLE if (sel := names == e).any()}
    fig, axes = figure(ctx, f"Parameters vs truth (band: truth ±{100 * TOL:.0f} %)", 4)
    clipped = False
    for ax, p in zip(axes, ORDER, strict=False):
        k, unit = SCALE[p]
        t_tr, v_tr = np.asarray(tr["t_s"], float), np.asarray(tr[p], float) * k
        tt, tv = envelope(t_tr, v_tr)
        ax.fill_between(
            *band(t_tr, v_tr - TOL * np.abs(v_tr), v_tr + TOL * np.abs(v_tr)),
            color="0.85",
            lw=0,
            label=f"truth ±{100 * TOL:.0f} %",
        )
        ax.plot(tt, tv, color="k", lw=1.0, ls="--", label="truth (plant)", zorder=2)
        known = tv[np.isfinite(tv)]  # a truth without this parameter: the estimates' own range
        lo, hi = (float(known.min()), float(known.max())) if len(known) else (-np.inf, np.inf)
        y0, y1 = lo * (1 - ZOOM), hi * (1 + ZOOM)
        for e, sel in rows.items():
            v = np.asarray(par[p], float)[sel] * k
            ax.plot(
                *envelope(t_all[sel], v),
                label=e if e != "nominal" else "nominal (motor file)",
                **STYLE[e],
            )
            clipped = clipped or bool(np.any((v < y0) | (v > y1)))
        if len(known):
            ax.set_ylim(y0, y1)
        segment_markers(ax, ctx, label=p == ORDER[0])
        ax.set_ylabel(f"{LABEL[p]} ({unit})")
    legend(axes[0])
    time_axis(axes[-1])
    if clipped:
        axes[-1].annotate(
            f"y ranges: truth ±{100 * ZOOM:.0f} %; estimates outside are clipped",
            xy=(0.0, -0.32),
            xycoords="axes fraction",
            fontsize=8,
            color="0.35",
            va="top",
        )
    return fig
