"""Plots for a run: `build_report(log, out_dir)` writes one PNG per panel that has data and one
self-contained HTML page (PNGs embedded, the per-segment summary and the identification table).

Panels (docs/report.md): speed, dq currents, dq voltages, parameters vs truth, angle and speed
estimation error, capture waveforms. A panel without data is skipped, with the reason in the page.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass, field
from pathlib import Path

from pmsm_hil.analysis import report_capture, report_params, report_signals
from pmsm_hil.analysis.reading import ANALYSIS_TOPICS, other_kind, recover_hint
from pmsm_hil.analysis.report_context import READS as CONTEXT_READS
from pmsm_hil.analysis.report_context import run_context
from pmsm_hil.log.reader import Log, LogFormatError, merge_topics, path_problem, read_log

# key (file name), title, function, caption
PANELS = (
    (
        "speed",
        "Speed",
        report_signals.speed,
        "Reference, encoder speed, the speed the firmware uses (when it differs) and, on the "
        "emulator, the plant's own speed.",
    ),
    (
        "currents",
        "dq currents",
        report_signals.currents,
        "Measured d and q currents at the telemetry rate against their references.",
    ),
    (
        "voltages",
        "dq voltages",
        report_signals.voltages,
        "Commanded d and q voltages: light, each telemetry sample (one switching vector of the MPCC); "
        "bold, their 20 ms mean; dashed, the linear modulation limit V_dc/√3.",
    ),
    (
        "parameters",
        "Parameters vs truth",
        report_params.parameters,
        "Each estimator's L_d, L_q, ψ_f and R against the plant's truth, with the ±2 % convergence band.",
    ),
    (
        "estimation_error",
        "Angle and speed estimation error",
        report_signals.estimation_error,
        "Electrical angle and speed the firmware uses minus the encoder's.",
    ),
    (
        "capture",
        "Capture waveforms",
        report_capture.capture,
        "At the control rate: phase currents; each leg's duty (its switch state averaged over 20 "
        "control periods); the DC-link voltage; the switch states of the first 60 periods. "
        "Switch states are recorded under the MPCC only: not where FOC ran.",
    ),
)

# what the report reads of a log: the panels' fields, the run's context, the summary's and the
# identification table's; nothing else is decoded (tests/test_report.py: the same panels as from
# the whole log)
REPORT_TOPICS = merge_topics(
    ANALYSIS_TOPICS, CONTEXT_READS, report_signals.READS, report_params.READS, report_capture.READS
)


class ReportError(Exception):
    """Bad input for a report: the message says what and where."""


@dataclass
class Report:
    out_dir: Path
    html: Path
    pngs: dict[str, Path] = field(default_factory=dict)  # key -> file
    skipped: dict[str, str] = field(default_factory=dict)  # key -> reason


def _png(fig) -> bytes:
    from pmsm_hil.analysis.report_style import DPI, close

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    close(fig)
    return buf.getvalue()


def _tables(path: Path, log: Log, notes: list[str]):
    from pmsm_hil.analysis.identification import identification_table
    from pmsm_hil.analysis.summary import summarize_log

    summary = ident = None
    try:
        summary = summarize_log(path, log)
    except (KeyError, ValueError, IndexError) as e:
        notes.append(f"The per-segment summary could not be computed: {e}")
    try:
        ident = identification_table(path, log=log)
    except (KeyError, ValueError, IndexError) as e:
        notes.append(f"The identification table could not be computed: {e}")
    return summary, ident


def _out_problem(out: Path) -> str | None:
    """Why the report cannot go to the folder ``out``, or None (a file of that name; a folder
    without write permission; an ancestor that is a file)."""
    if out.exists() and not out.is_dir():
        return f"-o {out}: is a file; give a folder for the PNGs and report.html"
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                return f"-o {out}: {parent} is a file, not a folder"
            break
    probe = out if out.is_dir() else next((p for p in out.parents if p.exists()), None)
    if probe is not None and not os.access(probe, os.W_OK | os.X_OK):
        return f"-o {out}: cannot write in {probe} (permission denied)"
    return None


def build_report(log_path: Path | str, out_dir: Path | str | None = None) -> Report:
    """Write the report of the log at `log_path` into `out_dir` (default: LOG-report/ beside it)."""
    path = Path(log_path)
    why = path_problem(log_path)
    if why:
        raise ReportError(why)
    out = Path(out_dir) if out_dir is not None else path.with_name(path.stem + "-report")
    why = _out_problem(out)  # before the log is read: an hour's log takes half a minute
    if why:
        raise ReportError(why)
    try:
        log = read_log(path, topics=REPORT_TOPICS)
    except LogFormatError as e:
        raise ReportError(str(e)) from None
    except OSError as e:
        raise ReportError(f"{path}: cannot read ({e.strerror or e})") from None
    kind = other_kind(log)
    if kind:
        raise ReportError(f"{path}: {kind}")
    ctx = run_context(log, path)
    if not ctx.has("/pmsm/telemetry") and not ctx.has("/pmsm/capture"):
        raise ReportError(
            f"{path}: no telemetry in the log (empty, or cut off before the first "
            f"chunk): nothing to plot{recover_hint(path)}"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ReportError(f"-o {out}: cannot create the directory ({e.strerror or e})") from None
    notes: list[str] = []
    summary, ident = _tables(path, log, notes)  # from the log read once
    report = Report(out_dir=out, html=out / "report.html")
    panels: list[tuple[str, str, bytes | None, str]] = []
    for key, title, fn, caption in PANELS:
        res = fn(ctx)
        if isinstance(res, str):
            report.skipped[key] = res
            panels.append((key, title, None, res))
            continue
        png = _png(res)
        report.pngs[key] = out / f"{key}.png"
        panels.append((key, title, png, caption))
    from pmsm_hil.analysis.report_html import page

    html = page(ctx, panels, summary, ident, notes)
    try:
        for key, _, png_bytes, _ in panels:
            if png_bytes is not None:
                report.pngs[key].write_bytes(png_bytes)
        report.html.write_text(html, encoding="utf-8")
    except OSError as e:
        raise ReportError(f"-o {out}: cannot write the report ({e.strerror or e})") from None
    return report
