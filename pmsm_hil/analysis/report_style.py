"""The look shared by every report figure: the Agg backend, the title carrying the run's identity,
segment markers, and legends placed outside the axes so that they hide no data."""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from pmsm_hil.analysis.report_context import RunContext

WIDTH_IN = 11.0
ROW_IN = 2.6
DPI = 110


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
