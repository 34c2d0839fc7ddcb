"""Report panel: the control-rate capture (/pmsm/capture): phase currents, switch states of the
three legs, DC-link voltage."""
from __future__ import annotations

import numpy as np

from pmsm_hil.analysis.report_context import RunContext
from pmsm_hil.analysis.report_style import figure, legend

CAP = "/pmsm/capture"


def capture(ctx: RunContext):
    if not ctx.has(CAP):
        return "no /pmsm/capture samples in the log (no segment asked for a capture, or the upload failed)"
    cap = ctx.topic(CAP)
    t = np.asarray(cap["t_s"], float)
    t_ms = (t - t[0]) * 1e3
    fig, axes = figure(ctx, f"Capture at the control rate, from t = {t[0]:.4f} s", 3)
    ax = axes[0]
    for ph, c in zip("abc", ("C0", "C1", "C2")):
        ax.plot(t_ms, cap[f"i_{ph}_a"], lw=0.8, color=c, label=f"i_{ph}")
    ax.set_ylabel("phase current (A)")
    legend(ax)
    ax = axes[1]
    for j, (ph, c) in enumerate(zip("abc", ("C0", "C1", "C2"))):
        # legs stacked: leg a at 4..5, b at 2..3, c at 0..1 (1 = upper switch on)
        base = 2 * (2 - j)
        ax.step(t_ms, np.asarray(cap[f"s_{ph}"], float) * 0.8 + base, where="post", lw=0.7, color=c,
                label=f"s_{ph} (leg {ph})")
    ax.set_yticks([0, 0.8, 2, 2.8, 4, 4.8], ["c 0", "c 1", "b 0", "b 1", "a 0", "a 1"])
    ax.set_ylabel("switch state\n(1 = upper on)")
    ax.set_ylim(-0.4, 5.4)
    legend(ax)
    ax = axes[2]
    ax.plot(t_ms, cap["v_dc_v"], lw=0.8, color="C3", label="V_dc")
    ax.set_ylabel("DC-link voltage (V)")
    ax.set_xlabel("time since the capture's first sample (ms)")
    legend(ax)
    return fig
