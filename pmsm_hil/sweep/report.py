"""`pmsm-hil sweep report DIR`: from DIR/results.parquet, a table of every metric (runs, median,
worst) in DIR/report/summary.md, one PNG per metric against each axis, and for a sweep with two
grid axes a pass/fail map over the grid (pass: the run is ok, complete, without faults and, when
the profile has acceptance criteria, within them)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

from .results import FIRST_COLUMNS, LAST_COLUMNS, read_table

__all__ = ["ReportError", "metric_columns", "passed", "write_report"]


class ReportError(Exception):
    pass


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


def passed(row: dict[str, Any]) -> bool:
    if row.get("status") != "ok":
        return False
    if row.get("complete") is False or (row.get("faults") or 0) > 0:
        return False
    return row.get("acceptance_failed", 0) in (0, None) or (
        isinstance(row.get("acceptance_failed"), float) and math.isnan(row["acceptance_failed"])
    )


def _finite(xs):
    return [
        x
        for x in xs
        if isinstance(x, (int, float)) and not (isinstance(x, float) and math.isnan(x))
    ]


def _summary(rows, cols) -> str:
    ok = [r for r in rows if r.get("status") == "ok"]
    lines = [
        f"# Sweep results: {len(rows)} runs, {len(ok)} ok, {len(rows) - len(ok)} failed; "
        f"{sum(passed(r) for r in rows)} of {len(rows)} within the profile's acceptance criteria "
        "(complete, no fault)",
        "",
        "| metric | runs | median | worst (largest magnitude) | min | max |",
        "|---|---|---|---|---|---|",
    ]
    for c in cols:
        v = _finite([float(r[c]) for r in ok if r.get(c) is not None])
        if not v:
            lines.append(f"| {c} | 0 | | | | |")
            continue
        v.sort()
        med = v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])
        worst = max(v, key=abs)
        lines.append(f"| {c} | {len(v)} | {med:.4g} | {worst:.4g} | {v[0]:.4g} | {v[-1]:.4g} |")
    return "\n".join(lines) + "\n"


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def write_report(out: Path) -> list[Path]:
    """Write the report of the sweep in ``out``; return the files written."""
    from pmsm_hil.analysis.report_style import plt

    if not (out / "results.parquet").is_file():
        raise ReportError(
            f"{out}: no results.parquet here (run `pmsm-hil sweep SWEEP --out {out}` first)"
        )
    rows = read_table(out)
    if not rows:
        raise ReportError(f"{out}/results.parquet: the table is empty")
    meta = (
        json.loads((out / "sweep.json").read_text())
        if (out / "sweep.json").is_file()
        else {"axes": []}
    )
    axes = [a["name"] for a in meta["axes"] if a["name"] in rows[0]]
    cols = metric_columns(rows, axes)
    rep = out / "report"
    rep.mkdir(exist_ok=True)
    written = [rep / "summary.md"]
    written[0].write_text(_summary(rows, cols))
    ok = [r for r in rows if r.get("status") == "ok"]
    num_axes = [a for a in axes if all(isinstance(r.get(a), (int, float)) for r in rows)]
    if num_axes and ok:
        for c in cols:
            fig, axs = plt.subplots(
                1,
                len(num_axes),
                figsize=(3.2 * len(num_axes) + 1, 3.2),
                squeeze=False,
                layout="constrained",
            )
            for ax, a in zip(axs[0], num_axes, strict=False):
                good = [r for r in ok if passed(r)]
                bad = [r for r in ok if not passed(r)]
                ax.plot([r[a] for r in good], [float(r[c]) for r in good], "o", ms=4, label="pass")
                if bad:
                    ax.plot(
                        [r[a] for r in bad],
                        [float(r[c]) for r in bad],
                        "x",
                        color="C3",
                        label="fail",
                    )
                ax.set_xlabel(a, fontsize=8)
                ax.grid(alpha=0.3)
            axs[0][0].set_ylabel(c, fontsize=8)
            fig.suptitle(f"{meta.get('name', out.name)}: {c}", fontsize=10)
            p = rep / f"{_safe(c)}.png"
            fig.savefig(p, dpi=90)
            plt.close(fig)
            written.append(p)
    grid = [
        a["name"]
        for a in meta["axes"]
        if a["kind"] in ("values", "linspace")
        and a["name"] in rows[0]
        and len({r[a["name"]] for r in rows}) > 1
    ]
    if len(grid) == 2:
        written.append(_pass_map(rows, grid, rep, meta.get("name", out.name)))
    return written


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
    ax.set_xticks(range(len(xs)), [f"{x:.4g}" for x in xs], fontsize=7, rotation=45)
    ax.set_yticks(range(len(ys)), [f"{y:.4g}" for y in ys], fontsize=7)
    ax.set_xlabel(xa, fontsize=8)
    ax.set_ylabel(ya, fontsize=8)
    fig.colorbar(im, ax=ax, label="share of runs passed")
    ax.set_title(f"{name}: pass/fail", fontsize=10)
    p = rep / "pass_map.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    return p
