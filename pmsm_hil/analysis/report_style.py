"""The look shared by every report figure: the Agg backend, the title carrying the run's identity,
segment markers, and legends placed outside the axes so that they hide no data."""

from __future__ import annotations

import warnings
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
# two per pixel column of the axes (WIDTH_IN * DPI = 1210 px for the whole figure, some 950 for
# an axes beside its legend). Four per column drew the same picture (docs/report.md) at twice the
# time: Agg's cost grows with the envelope's overlapping strokes, not with the pixels.
ENVELOPE_SLICES = 2000


def envelope(
    t: np.ndarray, y: np.ndarray, slices: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The samples a line plot of (t, y) shows at the figure's resolution: in each of ``slices``
    runs of equal count, the minimum and the maximum in time order (an oscilloscope's peak
    detect), the remainder as it is (``slices``: ENVELOPE_SLICES). A short series is returned
    unchanged. NaNs are skipped
    within a run; a run of NaNs only keeps one, a gap as in the full line. An hour of telemetry
    (7.2 M samples) is drawn from 4000 points, not rendered in full."""
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


def band(
    t: np.ndarray, lo: np.ndarray, hi: np.ndarray, slices: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A band between ``lo`` and ``hi`` at the figure's resolution, for ``fill_between``: in each
    of ``slices`` runs of equal count, the least ``lo`` and the greatest ``hi`` held from the
    run's first sample to the next run's (the remainder as it is; a short series unchanged). It
    covers every sample's band, as the full fill would, with a polygon that does not cross itself:
    the envelope's zigzag filled cost Agg some 15 times the time."""
    slices = ENVELOPE_SLICES if slices is None else slices
    t = np.asarray(t)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    n = len(t)
    if n <= 2 * slices:
        return t, lo, hi
    k = n // slices
    m = k * slices
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a run of NaNs only: a gap
        run_lo = np.nanmin(lo[:m].reshape(slices, k), axis=1)
        run_hi = np.nanmax(hi[:m].reshape(slices, k), axis=1)
    starts = t[:m:k]
    ends = np.append(starts[1:], t[m] if m < n else t[-1])
    tt = np.stack([starts, ends], axis=1).reshape(-1)
    return (
        np.concatenate([tt, t[m:]]),
        np.concatenate([np.repeat(run_lo, 2), lo[m:]]),
        np.concatenate([np.repeat(run_hi, 2), hi[m:]]),
    )


def figure(
    ctx: RunContext, what: str, rows: int, sharex: bool = True, note: str = ""
) -> tuple[Figure, list]:
    """A figure of `rows` stacked axes, titled `what — profile · rig · seed`, and `note` on a
    second line of the title when given."""
    fig, axes = plt.subplots(
        rows,
        1,
        figsize=(WIDTH_IN, 1.1 + ROW_IN * rows),
        sharex=sharex,
        squeeze=False,
        layout="constrained",
    )
    fig.suptitle(f"{what} — {ctx.tag}" + (f"\n{note}" if note else ""), fontsize=11)
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
