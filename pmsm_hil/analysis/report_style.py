"""The look shared by every report figure: the Agg backend, the title carrying the run's identity,
segment markers, and legends placed outside the axes so that they hide no data."""

from __future__ import annotations

from typing import Any

import matplotlib
import numpy as np

matplotlib.use("Agg")

import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from pmsm_hil.analysis.report_context import RunContext

WIDTH_IN = 11.0
ROW_IN = 2.6
DPI = 110
# a line of more samples than twice this is drawn as its envelope over this many slices: about
# four slices per pixel of the axes (WIDTH_IN * DPI = 1210 px for the whole figure)
ENVELOPE_SLICES = 4000


def envelope(
    t: np.ndarray, y: np.ndarray, slices: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The samples a line plot of (t, y) shows at the figure's resolution: in each of ``slices``
    runs of equal count, the minimum and the maximum in time order (an oscilloscope's peak
    detect), the remainder as it is (``slices``: ENVELOPE_SLICES). A short series is returned
    unchanged. NaNs are skipped
    within a run; a run of NaNs only keeps one, a gap as in the full line. An hour of telemetry
    (7.2 M samples) is drawn from 8000 points, not rendered in full."""
    slices = ENVELOPE_SLICES if slices is None else slices
    t = np.asarray(t)
    y = np.asarray(y, float)
    n = len(y)
    if n <= 2 * slices:
        return t, y
    k = n // slices
    m = k * slices
    runs = y[:m].reshape(slices, k)
    if np.isfinite(runs).all():  # no copy of the series (an hour's is 58 MB a copy)
        lo, hi = runs.argmin(axis=1), runs.argmax(axis=1)
    else:
        finite = np.isfinite(runs)
        lo = np.where(finite, runs, np.inf).argmin(axis=1)
        hi = np.where(finite, runs, -np.inf).argmax(axis=1)
    base = np.arange(slices) * k
    idx = np.stack([base + np.minimum(lo, hi), base + np.maximum(lo, hi)], axis=1).reshape(-1)
    idx = np.concatenate([idx, np.arange(m, n)])
    return t[idx], y[idx]


def figure(ctx: RunContext, what: str, rows: int, sharex: bool = True) -> tuple[Figure, list]:
    """A figure of `rows` stacked axes, titled `what — profile · rig · seed`."""
    fig, axes = plt.subplots(
        rows,
        1,
        figsize=(WIDTH_IN, 1.1 + ROW_IN * rows),
        sharex=sharex,
        squeeze=False,
        layout="constrained",
    )
    fig.suptitle(f"{what} — {ctx.tag}", fontsize=11)
    column = list(axes[:, 0])
    for ax in column:
        ax.grid(alpha=0.3)
    return fig, column


def legend(ax: Axes, **kw: Any) -> None:
    """Legend to the right of the axes: it never covers a curve."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            borderaxespad=0.0,
            fontsize=8,
            frameon=False,
            **kw,
        )


def segment_markers(ax: Axes, ctx: RunContext, label: bool = False) -> None:
    """A dotted line at each segment start; with `label`, the segment index above the axes."""
    for s in ctx.segments:
        ax.axvline(s.t_start_s, color="0.55", lw=0.7, ls=":", zorder=0)
        if label:
            ax.annotate(
                str(s.index),
                xy=(s.t_start_s, 1.0),
                xycoords=("data", "axes fraction"),
                xytext=(2, 2),
                textcoords="offset points",
                fontsize=7,
                color="0.35",
                va="bottom",
            )


def time_axis(ax: Axes) -> None:
    ax.set_xlabel("device time t (s)")


def close(fig: Figure) -> None:
    plt.close(fig)
