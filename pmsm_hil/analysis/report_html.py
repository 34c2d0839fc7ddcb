"""The report's single HTML page: self-contained (the PNGs are embedded as base64), with the run's
identity, the panels (or why a panel was skipped), the per-segment summary and the
identification table."""

from __future__ import annotations

import base64
import math
from html import escape
from typing import TYPE_CHECKING

from pmsm_hil.analysis.identification import ESTIMATORS, TOL, UNITS, IdentTable

if TYPE_CHECKING:
    from pmsm_hil.analysis.report_context import RunContext
    from pmsm_hil.analysis.summary import RunSummary

CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 78em; color: #222; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.9em; margin: 0.5em 0; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: right; }
th { background: #f0f0f0; } td.l, th.l { text-align: left; }
.bad { color: #b00; font-weight: bold; } .ok { color: #070; }
.note { background: #fff6d6; padding: 0.4em 0.8em; border-left: 4px solid #e0b000; }
.skipped { color: #666; font-style: italic; }
img { max-width: 100%; border: 1px solid #ddd; }
"""


def _table(head: list[str], rows: list[list[str]], left: int = 1) -> str:
    th = "".join(
        f'<th class="l">{escape(h)}</th>' if i < left else f"<th>{escape(h)}</th>"
        for i, h in enumerate(head)
    )
    body = []
    for r in rows:
        body.append(
            "<tr>"
            + "".join(
                f'<td class="l">{c}</td>' if i < left else f"<td>{c}</td>" for i, c in enumerate(r)
            )
            + "</tr>"
        )
    return f"<table><tr>{th}</tr>{''.join(body)}</table>"


def _mark(ok: bool | None, text: str) -> str:
    if ok is None:
        return escape(text)
    return f'<span class="{"ok" if ok else "bad"}">{escape(text)}</span>'


def _num(x: float | None, fmt: str) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    return format(x, fmt)


def summary_html(summary: RunSummary | None) -> str:
    if summary is None or not summary.segments:
        return '<p class="skipped">No segment could be summarised (no segment_start events or telemetry).</p>'
    has_truth = any(s.true_mean_error_rpm is not None for s in summary.segments)
    head = ["segment", "setpoint (r/min)", "load (N·m)", "mean error (r/min)"]
    head += ["plant mean error (r/min)"] if has_truth else []
    head += ["band (r/min)", "recovery (s)", "ripple i_d (A rms)", "ripple i_q (A rms)", "faults"]
    rows = []
    for s in summary.segments:
        row = [
            escape(f"{s.index} {s.name}"),
            f"{s.setpoint_rpm:.1f}",
            f"{s.load_nm:.2f}",
            _mark(s.mean_ok, _num(s.mean_error_rpm, "+.3f")),
        ]
        if has_truth:
            te = s.true_mean_error_rpm
            row.append("–" if te is None else _mark(abs(te) <= s.band_rpm, f"{te:+.3f}"))
        row += [
            f"±{s.band_rpm:.2f}",
            _mark(
                s.recovery_ok,
                "never"
                if s.recovery_s is not None and math.isinf(s.recovery_s)
                else _num(s.recovery_s, ".3f"),
            ),
            _num(s.ripple_d_a, ".3f"),
            _num(s.ripple_q_a, ".3f"),
            str(s.faults),
        ]
        rows.append(row)
    from rich.text import Text

    from pmsm_hil.analysis.summary_text import verdict_text

    # the console's verdict (an incomplete run says so, a fault is named), without its markup
    verdict = Text.from_markup(verdict_text(summary)).plain
    n = len(summary.segments)
    out = [
        _table(head, rows),
        f"<p>{n} segment{'' if n == 1 else 's'}, {summary.duration_s:.2f} s: "
        f"{_mark(summary.ok, verdict)} (definitions: docs/analysis.md)</p>",
    ]
    out += [f'<p class="bad">fault {escape(f)}</p>' for f in summary.faults]
    return "\n".join(out)


def ident_html(table: IdentTable | None) -> str:
    if table is None or not table.cells:
        return '<p class="skipped">No estimator ran in this run (no rls / adaline / nlms_adaline in /pmsm/params).</p>'
    ests = [e for e in ESTIMATORS if table.cell(e, "l_d_h") is not None]
    head = ["parameter", "truth"]
    for e in ests:
        head += [f"{e} final", f"{e} error", f"{e} t_conv (s)"]
    rows = []
    for p in ("l_d_h", "l_q_h", "r_s_ohm", "psi_f_wb"):
        name, unit, k = UNITS[p]
        c0 = table.cell(ests[0], p)
        assert c0 is not None  # every listed estimator has every parameter
        row = [escape(f"{name} ({unit})"), f"{c0.truth * k:.4g}"]
        for e in ests:
            c = table.cell(e, p)
            assert c is not None
            ok = abs(c.error_rel) <= TOL
            row += [f"{c.final * k:.4g}", _mark(ok, f"{100 * c.error_rel:+.2f} %"), c.conv_text()]
        rows.append(row)
    return (
        _table(head, rows)
        + f"<p>Truth: {escape(table.truth_source)}; window t = {table.t0_s:.3f} … {table.t1_s:.3f} s; "
        f"final = mean over the last 50 ms; t_conv: from the first update until the estimate stays "
        f"within ±{100 * TOL:.0f} % (docs/identification.md).</p>"
    )


def page(
    ctx: RunContext,
    panels: list[tuple[str, str, bytes | None, str]],
    summary: RunSummary | None,
    ident: IdentTable | None,
    extra_notes: list[str],
) -> str:
    """panels: list of (key, title, png bytes or None, caption or skip reason)."""
    meta = ctx.log.metadata
    run, dev = meta.get("run", {}), meta.get("device", {})
    info = [
        ("profile", run.get("profile", "")),
        ("motor", run.get("motor", "")),
        ("rig", ctx.rig or "–"),
        ("seed", ctx.seed or "– (a rig)"),
        ("board", f"{dev.get('board', '')} firmware {dev.get('fw_version', '')}"),
        ("transport", run.get("transport", "")),
        ("log", str(ctx.path)),
    ]
    parts = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>pmsm-hil report: "
        f"{escape(ctx.tag)}</title><style>{CSS}</style></head><body>",
        f"<h1>pmsm-hil run report — {escape(ctx.tag)}</h1>",
        _table(["", ""], [[escape(k), escape(v)] for k, v in info], left=2),
    ]
    for n in ctx.notes + extra_notes:
        parts.append(f'<p class="note">{escape(n)}</p>')
    drawn = [p for p in panels if p[2] is not None]
    skipped = [p for p in panels if p[2] is None]
    parts.append(
        "<h2>Panels</h2><ul>"
        + "".join(f'<li><a href="#panel-{k}">{escape(title)}</a></li>' for k, title, _, _ in drawn)
        + "</ul>"
    )
    for k, title, _, why in skipped:
        parts.append(
            f'<p class="skipped" id="skipped-{k}">{escape(title)}: skipped — {escape(why)}.</p>'
        )
    parts.append("<h2>Per-segment summary</h2>" + summary_html(summary))
    parts.append("<h2>Identification</h2>" + ident_html(ident))
    for k, title, png, caption in drawn:
        b64 = base64.b64encode(png).decode("ascii")  # type: ignore[arg-type]  # drawn: not None
        parts.append(
            f'<h2 id="panel-{k}">{escape(title)}</h2>'
            f'<img alt="{escape(title)}" src="data:image/png;base64,{b64}">'
            + (f"<p>{escape(caption)}</p>" if caption else "")
        )
    if ctx.segments:
        parts.append(
            "<h2>Segments</h2>"
            + _table(
                ["index", "name", "start (s)"],
                [[str(s.index), escape(s.name), f"{s.t_start_s:.3f}"] for s in ctx.segments],
                left=2,
            )
        )
    parts.append("</body></html>")
    return "\n".join(parts)
