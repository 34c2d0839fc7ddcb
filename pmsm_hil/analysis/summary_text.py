"""The run summary as text: the per-segment table fitted to the terminal, what the run missed, and
the one-line verdict (`analyze`, the end of `run`, `report`'s page); the figures themselves are
pmsm_hil.analysis.summary's."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pmsm_hil.analysis.summary import RECOVERY_LIMIT_S

if TYPE_CHECKING:
    from rich.console import Console

    from pmsm_hil.analysis.summary import RunSummary


def estimator_text(e: dict) -> str:
    if e["theta_err_mean_rad"] is None:
        return f"estimator {e['estimator']}: did not close the loop"
    lock = (
        "locked throughout"
        if not e["unlocked_frames"]
        else f"[red]out of lock in {e['unlocked_frames']} frames from t = "
        f"{e['first_unlocked_s']:.3f} s[/]"
    )
    return (
        f"estimator {e['estimator']} closed the loop for {e['in_loop_s']:.2f} s: theta_err "
        f"mean {e['theta_err_mean_rad']:+.4f} rad, RMS {e['theta_err_rms_rad']:.4f}, largest "
        f"{e['theta_err_max_rad']:.4f}; {lock}"
    )


# columns of the printed summary: (header, short header, priority: the lowest goes first when narrow)
_COLUMNS = (
    ("seg", "seg", 9),
    ("name", "name", 8),
    ("setpoint r/min", "set r/min", 7),
    ("load N·m", "load N·m", 2),
    ("mean err r/min", "err r/min", 9),
    ("true err r/min", "true err", 5),
    ("band", "band", 3),
    ("recovery s", "rec s", 6),
    ("ripple d/q A", "ripple d/q A", 1),
    ("faults", "flt", 10),  # a fault is never hidden by a narrow terminal
)


def _num(x: float, spec: str) -> str:
    """A figure, or a dash where the window held no sample."""
    return "—" if math.isnan(x) else format(x, spec)


def _summary_rows(summary: RunSummary) -> list[dict[str, str]]:
    rows = []
    for s in summary.segments:
        ok = ("[green]" if s.mean_ok else "[red]") if s.mean_judged else "[dim]"
        te = s.true_mean_error_rpm
        te_ok = (
            "[dim]"
            if not s.mean_judged
            else ("[green]" if te is not None and abs(te) <= s.band_rpm else "[red]")
        )
        rows.append(
            {
                "seg": str(s.index),
                "name": s.name,
                "setpoint r/min": f"{s.setpoint_rpm:.1f}",
                "load N·m": f"{s.load_nm:.2f}",
                "mean err r/min": f"{ok}{_num(s.mean_error_rpm, '+.3f')}"
                + ("" if s.mean_judged else " short" if math.isnan(s.mean_error_rpm) else " ramp"),
                "true err r/min": "" if te is None else f"{te_ok}{te:+.3f}",
                "band": f"±{s.band_rpm:.2f}",
                "recovery s": ""
                if s.recovery_s is None
                else ("[green]" if s.recovery_ok else "[red]")
                + ("never" if math.isinf(s.recovery_s) else f"{s.recovery_s:.3f}"),
                "ripple d/q A": f"{_num(s.ripple_d_a, '.3f')}/{_num(s.ripple_q_a, '.3f')}",
                "faults": str(s.faults),
            }
        )
    return rows


def print_summary(
    summary: RunSummary,
    console: Console | None = None,
    interrupted: bool = False,
    error: bool = False,
) -> None:
    """The per-segment table, fitted to the terminal: on a narrow one the least important columns
    are left out (and named) rather than cut short."""
    from rich import box
    from rich.console import Console
    from rich.measure import Measurement
    from rich.table import Table

    if console is None:
        console = Console()
        if not console.is_terminal:
            console = Console(width=max(console.width, 160))
    has_truth = any(s.true_mean_error_rpm is not None for s in summary.segments)
    cols = [c for c in _COLUMNS if has_truth or c[0] != "true err r/min"]
    rows = _summary_rows(summary)
    narrow = console.width < 120
    hidden = []

    def table(cs):
        tab = Table(
            title=f"run summary: {summary.path}" + (f" ({summary.run})" if summary.run else ""),
            header_style="bold",
            box=box.SIMPLE_HEAD if narrow else box.HEAVY_HEAD,
        )
        for key, short, _ in cs:
            tab.add_column(
                short if narrow else key, justify="left" if key == "name" else "right", no_wrap=True
            )
        for r in rows:
            tab.add_row(*(r[key] for key, _, _ in cs))
        return tab

    tab = table(cols)
    wide = console.options.update_width(10_000)
    while Measurement.get(console, wide, tab).maximum > console.width and len(cols) > 3:
        drop = min(cols, key=lambda c: c[2])
        cols.remove(drop)
        hidden.append(drop[0])
        tab = table(cols)
    console.print(tab)
    if hidden:
        console.print(
            f"[dim]not shown at {console.width} columns: {', '.join(hidden)} "
            f"(`pmsm-hil analyze LOG --json` has every column)[/]",
            highlight=False,
        )
    for f in summary.faults:
        console.print(f"[red]fault[/] {f}")
    for p in summary.problems:
        console.print(f"[yellow]log[/] {p}")
    if summary.estimator:
        console.print(estimator_text(summary.estimator), highlight=False)
    n = len(summary.segments)
    console.print(
        f"{n} segment{'' if n == 1 else 's'}, {summary.duration_s:.2f} s: "
        f"{verdict_text(summary, interrupted, error)}",
        highlight=False,
    )


def missed_text(summary: RunSummary, most: int = 4) -> str:
    """Which plateau bounds the run missed, by segment: the mean speed error beyond its band, a
    recovery beyond RECOVERY_LIMIT_S, faults ("" when none)."""
    out = []
    for s in summary.segments:
        what = []
        if not s.mean_ok:
            what.append(f"mean speed error {s.mean_error_rpm:+.2f} r/min beyond ±{s.band_rpm:g}")
        if s.recovery_ok is False and s.recovery_s is not None:
            rec = "never" if math.isinf(s.recovery_s) else f"{s.recovery_s:.2f} s"
            what.append(f"recovery {rec} (bound {RECOVERY_LIMIT_S:g} s)")
        if what:
            out.append(f"segment {s.index} {s.name!r} {', '.join(what)}")
    if summary.faults:
        n = len(summary.faults)
        out.append(f"{n} fault{'s' if n > 1 else ''} ({'; '.join(summary.faults[:3])})")
    if len(out) > most:
        out = [*out[:most], f"and {len(out) - most} more"]
    return "; ".join(out)


def verdict_text(summary: RunSummary, interrupted: bool = False, error: bool = False) -> str:
    """One line: whether every plateau the run was to play was seen and within its bounds;
    ``interrupted``: the user stopped the run (Ctrl-C), ``error``: a link or host error ended it
    (the error is printed after the summary)."""
    names = summary.expected

    def seg_list(idx: list[int]) -> str:
        if len(idx) == 1:
            i = idx[0]
            return f"segment {i} {names[i]!r}" if i < len(names) else f"segment {i}"
        runs, start = [], idx[0]
        for a, b in zip(idx, [*idx[1:], -1], strict=False):
            if b != a + 1:
                runs.append(f"{start}" if start == a else f"{start}-{a}")
                start = b
        return f"segments {', '.join(runs)} ({len(idx)} of {len(names)})"

    if summary.complete:
        if summary.ok:
            return "[green]all plateaus within bounds[/]"
        return "[red]generic plateau bounds missed[/]" + (
            f": {missed_text(summary)}" if missed_text(summary) else ""
        )
    parts = []
    if interrupted:
        parts.append("run interrupted")
    elif error:
        parts.append("the run ended on an error (below)")
    if summary.ended and summary.ended != "profile end":
        parts.append(summary.ended)
    elif not summary.ended:
        parts.append("the log ends before the run did")
    if summary.partial:
        parts.append(f"partial: {seg_list(summary.partial)}")
    if summary.missing:
        parts.append(f"missing: {seg_list(summary.missing)}")
    if summary.problems and not summary.partial and not summary.missing:
        # frames lost on the link or rejected by the device, a cut file: each named below (it
        # said "the file is damaged" of a whole file whose link had lost frames)
        parts.append("the record is not whole: " + "; ".join(summary.problems[:2]))
    missed = [s.index for s in summary.segments if not (s.mean_ok and s.recovery_ok is not False)]
    if summary.faults:  # what tripped, with when (a fault ends a run: it is never "within bounds")
        parts.append(
            f"{len(summary.faults)} fault{'s' if len(summary.faults) > 1 else ''}: "
            + "; ".join(summary.faults[:3])
        )
    if not summary.segments:
        return f"[red]INCOMPLETE[/] ({'; '.join(parts)}): no segment can be checked"
    if not summary.partial and not summary.missing:  # every segment played, the record not whole
        seen = "bounds missed in the segments" if missed else "the segments are within bounds"
        return f"[red]INCOMPLETE[/] ({'; '.join(parts)}): {seen}"
    seen = "bounds missed in the segments seen" if missed else "segments seen are within bounds"
    return f"[red]INCOMPLETE[/] ({'; '.join(parts)}): {seen}, the others were not checked"
