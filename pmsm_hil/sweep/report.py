"""`pmsm-hil sweep report DIR`: from DIR/results.parquet, a table of every metric (runs, median,
worst) in DIR/report/summary.md (and as ``SweepReport.stats`` for the console), one PNG per metric
against each axis, and for a sweep with two grid axes a pass/fail map over the grid (pass: the
run completed, whole, without faults and, when the profile has acceptance criteria, within
them)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .results import (
    FIRST_COLUMNS,
    LAST_COLUMNS,
    ResultsFormatError,
    has_criteria,
    passed,
    read_meta,
    read_table,
)

__all__ = [
    "MetricStats",
    "ReportError",
    "SweepReport",
    "metric_columns",
    "metric_stats",
    "passed",
    "stat_text",
    "write_report",
]


class ReportError(Exception):
    pass


@dataclass
class MetricStats:
    """One metric over the completed runs that have a value for it (NaN: none has)."""

    metric: str
    runs: int
    median: float
    worst: float  # the value of largest magnitude
    min: float
    max: float
    no_value: int = 0  # completed runs without a value (a convergence time: never converged)

    def runs_text(self) -> str:
        """The runs column: with a value, and how many completed runs have none (for a
        convergence time, the runs that never stayed within the band)."""
        if not self.no_value:
            return str(self.runs)
        what = "never" if self.metric.endswith("_conv_s") else "no value"
        return f"{self.runs} ({self.no_value} {what})"


@dataclass
class SweepReport:
    out: Path
    runs: int  # rows of the table
    completed: int  # runs that completed (status ok)
    met: int  # completed, whole, without fault, within the acceptance criteria
    criteria: bool  # the profile has acceptance criteria (else `met` counts whole, no fault)
    stats: list[MetricStats] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # e.g. an older directory's columns renamed
    failed: list[tuple[Any, str]] = field(default_factory=list)  # (run index, error) not run
    # (run index, log) of the runs an interrupt stopped (status interrupted: not failures; the
    # same sweep command runs them again)
    stopped: list[tuple[Any, str]] = field(default_factory=list)

    def headline(self) -> str:
        """Runs completed / failed to run / stopped, and how many met the criteria: one line."""
        ran = (
            f"{self.runs} runs: {self.completed} completed, "
            f"{self.runs - self.completed - len(self.stopped)} failed to run"
            + (f", {len(self.stopped)} stopped by an interrupt" if self.stopped else "")
        )
        if self.criteria:
            return (
                f"{ran}; {self.met} of {self.runs} met the profile's acceptance criteria "
                f"(and played the whole profile without a fault), {self.runs - self.met} did not"
            )
        return (
            f"{ran}; the profile has no acceptance criteria: {self.met} of {self.runs} "
            "played the whole profile without a fault"
        )


def metric_columns(rows: list[dict[str, Any]], axes: list[str]) -> list[str]:
    """The numeric metric columns (not the axes, not the bookkeeping), in table order."""
    skip = set(FIRST_COLUMNS) | set(LAST_COLUMNS) | set(axes)
    cols: list[str] = []
    for k in rows[0]:
        if k in skip:
            continue
        vals = [r.get(k) for r in rows]
        if all(isinstance(v, (int, float)) or v is None for v in vals):
            cols.append(k)
    return cols


def _finite(xs):
    return [
        x
        for x in xs
        if isinstance(x, (int, float)) and not (isinstance(x, float) and math.isnan(x))
    ]


def metric_stats(rows: list[dict[str, Any]], cols: list[str]) -> list[MetricStats]:
    """Per metric column: runs with a value, median, worst (largest magnitude), min, max over
    the completed runs."""
    ok = [r for r in rows if r.get("status") == "ok"]
    out = []
    for c in cols:
        v = sorted(_finite([float(r[c]) for r in ok if r.get(c) is not None]))
        missing = len(ok) - len(v)
        if not v:
            out.append(MetricStats(c, 0, math.nan, math.nan, math.nan, math.nan, missing))
            continue
        med = v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])
        out.append(MetricStats(c, len(v), med, max(v, key=abs), v[0], v[-1], missing))
    return out


def stat_text(metric: str, x: float) -> str:
    """A statistic as the console and summary.md show it: relative errors in %, the rest in the
    column's unit (its name's suffix), 4 significant digits; an empty cell for no value."""
    if math.isnan(x):
        return ""
    if metric.endswith("_rel"):
        return f"{100 * x:+.2f} %"
    return f"{x:.4g}"


def _summary(rep: SweepReport) -> str:
    lines = [
        f"# Sweep results: {rep.headline()}",
        "",
        *[f"Note: {n}" for n in rep.notes],
        *([""] if rep.notes else []),
        "| metric | runs | median | worst (largest magnitude) | min | max |",
        "|---|---|---|---|---|---|",
    ]
    for m in rep.stats:
        if not m.runs:
            lines.append(f"| {m.metric} | {m.runs_text()} | | | | |")
            continue
        cells = [stat_text(m.metric, x) for x in (m.median, m.worst, m.min, m.max)]
        lines.append(f"| {m.metric} | {m.runs_text()} | " + " | ".join(cells) + " |")
    if rep.failed:
        lines += ["", "## Runs that failed to run", ""]
        lines += [f"- run {i}: {err}" for i, err in rep.failed]
    if rep.stopped:
        lines += [
            "",
            "## Runs stopped by an interrupt (the same sweep command runs them again)",
            "",
        ]
        lines += [
            f"- run {i}: " + (f"its log so far {log}" if log else "no log kept")
            for i, log in rep.stopped
        ]
    return "\n".join(lines) + "\n"


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def write_report(out: Path) -> SweepReport:
    """Write the report of the sweep in ``out``; return it (the files written, the statistics,
    the counts)."""
    out = Path(out)
    if not (out / "results.parquet").is_file():
        raise ReportError(
            f"{out}: no results.parquet here (run `pmsm-hil sweep SWEEP --out {out}` first)"
        )
    rows = read_table(out)
    if not rows:
        raise ReportError(
            f"{out}/results.parquet: the table is empty: no run finished (interrupted before the "
            f"first? `pmsm-hil sweep SWEEP --out {out}` again resumes it)"
        )
    try:
        meta, notes = read_meta(out, rows)
    except ResultsFormatError as e:
        raise ReportError(str(e)) from None
    axes = [a["column"] for a in meta["axes"] if a["column"] in rows[0]]
    values = [a["value_column"] for a in meta["axes"] if a.get("value_column")]
    cols = metric_columns(rows, axes + values)
    report = SweepReport(
        out=out,
        runs=len(rows),
        completed=sum(1 for r in rows if r.get("status") == "ok"),
        met=sum(1 for r in rows if passed(r)),
        criteria=has_criteria(rows),
        stats=metric_stats(rows, cols),
        notes=notes,
        failed=[
            (r.get("index"), str(r.get("error") or ""))
            for r in rows
            if r.get("status") not in ("ok", "interrupted")
        ],
        stopped=[
            (r.get("index"), str(r.get("log_path") or ""))
            for r in rows
            if r.get("status") == "interrupted"
        ],
    )
    rep = out / "report"
    rep.mkdir(exist_ok=True)
    written = report.files
    written.append(rep / "summary.md")
    written[0].write_text(_summary(report))
    ok = [r for r in rows if r.get("status") == "ok"]
    plot_axes = [  # numbers, or names (a rig or motor file, `mtpa`/`id_zero`) as categories
        a
        for a in axes
        if (
            all(isinstance(r.get(a), (int, float)) for r in rows)
            or all(isinstance(r.get(a), str) for r in rows)
        )
        and len({r.get(a) for r in rows}) > 1  # a one-value axis is a fixed change: no panel
    ]
    if plot_axes and ok:
        for c in cols:
            p = rep / f"{_safe(c)}.png"
            _metric_plot(ok, c, plot_axes, f"{meta.get('name', out.name)}: {c}", p)
            written.append(p)
    grid = [
        a["column"]
        for a in meta["axes"]
        if a["kind"] in ("values", "linspace")
        and a["column"] in rows[0]
        and len({r[a["column"]] for r in rows}) > 1
    ]
    if len(grid) == 2:
        written.append(_pass_map(rows, grid, rep, meta.get("name", out.name)))
    for stale in set(rep.glob("*.png")) - set(written):  # an earlier report's metric or map
        stale.unlink()
    return report


PANELS_PER_ROW = 4


def _tick(v: Any) -> str:
    """An axis value as a tick label: a number in 4 digits, a name (a rig file) as it is."""
    return f"{v:.4g}" if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)


def _metric_plot(
    ok: list[dict[str, Any]], c: str, num_axes: list[str], title: str, p: Path
) -> None:
    """One metric against each axis, a panel per axis, at most PANELS_PER_ROW to a row; passing
    runs as dots, the others as crosses; a relative error in %, a whole-number axis (a seed) with
    whole-number ticks, an axis of names (rig files) with a tick per name."""
    from matplotlib.ticker import EngFormatter, MaxNLocator

    from pmsm_hil.analysis.report_style import plt
    from pmsm_hil.profiles._source import unit_of

    scale, unit = (100.0, " (%)") if c.endswith("_rel") else (1.0, "")
    ncols = min(PANELS_PER_ROW, len(num_axes))
    nrows = -(-len(num_axes) // ncols)
    # margins fixed in inches instead of a layout engine: constrained layout measured every
    # axis's extent before each save, half of a report's time (46 plots: 42 s)
    w_in, h_in = 3.2 * ncols + 1, 2.9 * nrows + 0.5
    fig, axs = plt.subplots(nrows, ncols, figsize=(w_in, h_in), squeeze=False)
    fig.subplots_adjust(
        left=0.9 / w_in,
        right=1 - 0.15 / w_in,
        bottom=0.55 / h_in,
        top=1 - 0.45 / h_in,
        wspace=0.35,
        hspace=0.55,
    )
    good = [r for r in ok if passed(r)]
    bad = [r for r in ok if not passed(r)]
    for k, ax in enumerate(axs.flat):
        if k >= len(num_axes):
            ax.set_visible(False)
            continue
        a = num_axes[k]
        names = sorted({r[a] for r in ok}) if isinstance(ok[0][a], str) else None

        def x(r: dict[str, Any], a: str = a, names: list | None = names) -> Any:
            return names.index(r[a]) if names is not None else r[a]

        ax.plot([x(r) for r in good], [scale * float(r[c]) for r in good], "o", ms=4, label="pass")
        if bad:
            ax.plot(
                [x(r) for r in bad],
                [scale * float(r[c]) for r in bad],
                "x",
                color="C3",
                label="fail",
            )
        ax.set_xlabel(a, fontsize=8)
        if names is not None:
            ax.set_xticks(range(len(names)), names, rotation=20 if len(names) > 2 else 0)
            ax.set_xlim(-0.5, len(names) - 0.5)
        else:
            whole = all(isinstance(r[a], int) and not isinstance(r[a], bool) for r in ok)
            # close values' long tick labels would touch: few ticks
            ax.xaxis.set_major_locator(MaxNLocator(nbins=4, integer=whole))
            if (
                0 < max(abs(float(r[a])) for r in ok) < 1e-2
            ):  # a dead time: 2 µs, not 2e-6 and an offset
                ax.xaxis.set_major_formatter(EngFormatter(unit=unit_of(a), sep=" "))
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
        if k % ncols == 0:
            ax.set_ylabel(c + unit, fontsize=8)
    if bad:
        fig.legend(
            *axs[0][0].get_legend_handles_labels(), loc="upper right", fontsize=7, frameon=False
        )
    fig.suptitle(title, fontsize=10)
    fig.savefig(p, dpi=90)
    plt.close(fig)


def _pass_map(rows, grid, rep: Path, name: str) -> Path:
    from pmsm_hil.analysis.report_style import plt

    xa, ya = grid
    xs = sorted({r[xa] for r in rows})
    ys = sorted({r[ya] for r in rows})
    import numpy as np

    frac = np.full((len(ys), len(xs)), np.nan)
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            cell = [r for r in rows if r[xa] == x and r[ya] == y]
            if cell:
                frac[j, i] = sum(passed(r) for r in cell) / len(cell)
    fig, ax = plt.subplots(figsize=(1.2 + 0.8 * len(xs), 1.2 + 0.6 * len(ys)), layout="constrained")
    im = ax.imshow(frac, cmap="RdYlGn", vmin=0, vmax=1, origin="lower", aspect="auto")
    ax.set_xticks(range(len(xs)), [_tick(x) for x in xs], fontsize=7, rotation=45)
    ax.set_yticks(range(len(ys)), [_tick(y) for y in ys], fontsize=7)
    ax.set_xlabel(xa, fontsize=8)
    ax.set_ylabel(ya, fontsize=8)
    fig.colorbar(im, ax=ax, label="share of runs passed")
    ax.set_title(f"{name}: pass/fail", fontsize=10)
    p = rep / "pass_map.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    return p
