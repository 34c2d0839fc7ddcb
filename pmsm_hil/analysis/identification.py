"""Identification table (paper A, Table 2) from any log with /pmsm/params: per parameter and
estimator the final value, its error against the truth, and the convergence time.

Truth: /sim/truth when the log has it (interpolated to each params message, so a drift step in the
plant is followed), else the motor file's values (metadata "motor").
Convergence time: from the estimator's first update (the first params message of that estimator
with a non-zero value of the parameter) to the first moment after which the estimate stays within
+-TOL (2 %) of the truth until the end of the window considered; None if it never settles.
The final value is the mean over the last FINAL_WINDOW_S (50 ms) of the window.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.log.reader import Log, read_log

if TYPE_CHECKING:
    from pmsm_hil.profiles import Profile

PARAMS = ("l_d_h", "l_q_h", "psi_f_wb", "r_s_ohm")
ESTIMATORS = ("rls", "adaline", "nlms_adaline")
TOL = 0.02
FINAL_WINDOW_S = 0.05
UNITS = {
    "l_d_h": ("L_d", "mH", 1e3),
    "l_q_h": ("L_q", "mH", 1e3),
    "psi_f_wb": ("psi_f", "Wb", 1.0),
    "r_s_ohm": ("R", "ohm", 1.0),
}

# Paper A, Table 2: (value, |error|, time s) per parameter and estimator, SI units.
PAPER_A_TABLE2 = {
    "rls": {
        "l_d_h": (4.4e-3, 0.6e-3, 0.8),
        "l_q_h": (9.31e-3, 2.69e-3, 0.8),
        "r_s_ohm": (1.42, 0.52, 0.2),
        "psi_f_wb": (0.194, 0.014, 0.15),
    },
    "adaline": {
        "l_d_h": (5.406e-3, 0.406e-3, 0.55),
        "l_q_h": (11.44e-3, 0.56e-3, 0.7),
        "r_s_ohm": (0.982, 0.082, 0.4),
        "psi_f_wb": (0.22, 0.04, 0.63),
    },
    "nlms_adaline": {
        "l_d_h": (5.013e-3, 0.013e-3, 0.322),
        "l_q_h": (12.06e-3, 0.06e-3, 0.47),
        "r_s_ohm": (0.982, 0.082, 0.32),
        "psi_f_wb": (0.182, 0.002, 0.37),
    },
}
# paper A's motor: the shipped files' names (paper-a-ipmsm, -measured) and what `commission`
# names its files of it (paper-a-ipmsm-commissioned)
PAPER_A_MOTOR = "paper-a-ipmsm"
PAPER_A_TRUE = {"l_d_h": 5e-3, "l_q_h": 12e-3, "psi_f_wb": 0.18, "r_s_ohm": 0.9}


@dataclass
class Cell:
    estimator: str
    param: str
    final: float
    truth: float
    error: float  # final - truth
    error_rel: float  # (final - truth) / truth
    t_first_s: float | None  # first update (device time)
    conv_s: float | None  # convergence time from the first update
    converged_flag: bool  # the firmware's own flag at the end
    step_s: float = 0.0  # the estimator's params period: the resolution of conv_s

    def conv_text(self, digits: int = 3) -> str:
        """conv_s for a table: "never", or "<step" when the first update already stays within
        the tolerance (the time is then only known to be shorter than one params period)."""
        if self.conv_s is None:
            return "never"
        if self.conv_s == 0.0 and self.step_s > 0.0:
            return f"<{self.step_s:.{digits}f}"
        return f"{self.conv_s:.{digits}f}"


@dataclass
class IdentTable:
    path: str
    truth_source: str
    t0_s: float
    t1_s: float
    cells: list[Cell] = field(default_factory=list)
    motor: str = ""  # the log's motor name ("": no motor metadata)

    def cell(self, estimator: str, param: str) -> Cell | None:
        for c in self.cells:
            if c.estimator == estimator and c.param == param:
                return c
        return None

    def as_dict(self) -> dict:
        return {
            "path": self.path,
            "truth_source": self.truth_source,
            "t0_s": self.t0_s,
            "t1_s": self.t1_s,
            "cells": [asdict(c) for c in self.cells],
        }


SECANT = {"l_d_h": "l_d_secant_h", "l_q_h": "l_q_secant_h"}
SECANT_SMOOTH_S = 0.05  # the secant follows the current ripple: averaged over this before use


def _smoothed(t: np.ndarray, x: np.ndarray, width_s: float) -> np.ndarray:
    """Centred moving average over width_s (samples evenly spaced in time)."""
    if len(t) < 3:
        return x
    n = max(1, round(width_s / max(float(np.median(np.diff(t))), 1e-9)))
    if n <= 1:
        return x
    k = np.ones(n) / n
    pad = np.pad(x, (n // 2, n - 1 - n // 2), mode="edge")
    return np.convolve(pad, k, mode="valid")


def _truth(log, t: np.ndarray, inductance: str = "secant") -> tuple[dict[str, np.ndarray], str]:
    """The reference per parameter at the times t. Inductances: the apparent (secant) ones the
    steady-state equations identify (docs/identification.md), when the log has them and
    `inductance` is "secant"; else the incremental ones."""
    tr = log.topic("/sim/truth") if "/sim/truth" in log.topics else None
    if tr is not None and len(tr["t_s"]):
        t_tr = np.asarray(tr["t_s"], float)
        out = {p: np.interp(t, t_tr, tr[p]) for p in PARAMS}
        have = all(k in tr and np.any(np.asarray(tr[k]) != 0.0) for k in SECANT.values())
        if inductance == "secant" and have:
            for p, k in SECANT.items():
                out[p] = np.interp(
                    t, t_tr, _smoothed(t_tr, np.asarray(tr[k], float), SECANT_SMOOTH_S)
                )
            return out, "/sim/truth (L: apparent, secant)"
        return out, "/sim/truth (L: incremental)"
    motor = log.metadata.get("motor", {})
    out = {}
    for p in PARAMS:
        v = float(motor[p]) if p in motor else PAPER_A_TRUE[p]
        out[p] = np.full_like(t, v, dtype=float)
    return out, "motor file" if motor else "paper A's motor (no motor metadata)"


def convergence_time(
    t: np.ndarray, est: np.ndarray, truth: np.ndarray, t_first: float, tol: float = TOL
) -> float | None:
    """Time from t_first to the first sample after which |est - truth| <= tol |truth| holds to the end."""
    ok = np.abs(est - truth) <= tol * np.abs(truth)
    if not len(ok) or not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    k = 0 if len(bad) == 0 else bad[-1] + 1
    return max(0.0, float(t[k]) - t_first)


def identification_window(profile: Profile) -> tuple[float, float]:
    """From 0 to the start of the first segment that steps the plant (the drift test), else the end."""
    steps = [s for s in profile.segments if getattr(s, "plant", None) is not None]
    return 0.0, (steps[0].t_start_s if steps else profile.total_duration_s)


# what the table reads of a log (read_log(path, topics=...))
IDENT_TOPICS = {"/pmsm/params": None, "/sim/truth": ("t_s", *PARAMS, *SECANT.values())}


def identification_table(
    path: Path | str,
    t0_s: float | None = None,
    t1_s: float | None = None,
    log: Log | None = None,
    inductance: str = "secant",
) -> IdentTable:
    """The table for the log at `path` (or ``log``, the file already read with at least
    IDENT_TOPICS), over device time [t0_s, t1_s] (default: from the first params message to the
    last one at which an estimate still changed, so that the final values are compared with the
    plant where the estimators last ran, not after a stop); inductances scored against the secant
    truth (default, when the log has it) or the incremental one."""
    log = log if log is not None else read_log(path, topics=IDENT_TOPICS)
    par = log.topic("/pmsm/params")
    t_all = np.asarray(par["t_s"], dtype=float)
    names = _names(par)
    t0 = float(t_all.min()) if t0_s is None and len(t_all) else (t0_s or 0.0)
    t1 = _last_change(par, t_all, names) if t1_s is None and len(t_all) else (t1_s or 0.0)
    table = IdentTable(str(path), "", t0, t1, motor=log.metadata.get("run", {}).get("motor", ""))
    for est in ESTIMATORS:
        sel = (names == est) & (t_all >= t0) & (t_all <= t1)
        if not np.any(sel):
            continue
        t = t_all[sel]
        truth, table.truth_source = _truth(log, t, inductance)
        conv_flag = bool(np.asarray(par["converged"])[sel][-1])
        step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
        for p in PARAMS:
            v = np.asarray(par[p], dtype=float)[sel]
            nz = np.nonzero(v != 0.0)[0]
            t_first = float(t[nz[0]]) if len(nz) else None
            last = t >= t[-1] - FINAL_WINDOW_S
            final = float(np.mean(v[last]))
            tr = float(np.mean(truth[p][last]))
            conv = (
                convergence_time(t[nz[0] :], v[nz[0] :], truth[p][nz[0] :], float(t[nz[0]]))
                if len(nz)
                else None
            )
            table.cells.append(
                Cell(
                    est,
                    p,
                    final,
                    tr,
                    final - tr,
                    (final - tr) / tr if tr else float("nan"),
                    t_first,
                    conv,
                    conv_flag,
                    step,
                )
            )
    return table


def _names(par) -> np.ndarray:
    """The params messages' estimator names, compared element by element with a name (``==``):
    the column as read (strings as objects), not made into a fixed-width string array, which for
    an hour's 1.4 M messages is some 70 MB."""
    names = np.asarray(par["estimator"])
    return names if names.dtype == object or names.dtype.kind == "U" else names.astype(str)


def _last_change(par, t_all: np.ndarray, names: np.ndarray) -> float:
    """The last params time at which an estimator's L_d, L_q or psi_f changed (the estimators
    stop with identification off or the motor stopped; the plant then moves on without them);
    the last message when none ever changed."""
    last = None
    for est in ESTIMATORS:
        sel = names == est
        if np.count_nonzero(sel) < 2:
            continue
        v = np.column_stack([np.asarray(par[p], dtype=float)[sel] for p in PARAMS[:3]])
        moved = np.nonzero(np.any(np.diff(v, axis=0) != 0.0, axis=1))[0]
        if len(moved):
            t = float(t_all[sel][moved[-1] + 1])
            last = t if last is None else max(last, t)
    return last if last is not None else float(t_all.max())


def _fmt(p: str, v: float) -> str:
    _, _, k = UNITS[p]
    return f"{v * k:.4g}"


def markdown_table(table: IdentTable, with_paper: bool = True) -> str:
    """Paper A's Table 2 beside ours, one row per parameter, as markdown."""
    ests = [e for e in ESTIMATORS if table.cell(e, "l_d_h") is not None]
    head = ["parameter", "truth"]
    for e in ests:
        head += [f"{e} value", f"{e} error", f"{e} t_conv s"]
        if with_paper:
            head += [f"paper {e} value", "paper error", "paper t s"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p in ("l_d_h", "l_q_h", "r_s_ohm", "psi_f_wb"):
        name, unit, _ = UNITS[p]
        c0 = table.cell(ests[0], p) if ests else None
        row = [f"{name} ({unit})", _fmt(p, c0.truth) if c0 else "-"]
        for e in ests:
            c = table.cell(e, p)
            assert c is not None  # every listed estimator has every parameter
            row += [_fmt(p, c.final), f"{100 * c.error_rel:+.2f} %", c.conv_text()]
            if with_paper:
                v, err, ts = PAPER_A_TABLE2[e][p]
                row += [_fmt(p, v), f"{100 * err / PAPER_A_TRUE[p]:.2f} %", f"{ts:.2f}"]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def text_table(table: IdentTable, with_paper: bool | None = None) -> str:
    """Plain-text version for the console: one block per estimator. ``with_paper`` None: paper A's
    Table 2 beside it only for paper A's motor, also as commissioned (or a log without motor
    metadata)."""
    if with_paper is None:
        with_paper = table.motor == "" or table.motor.startswith(PAPER_A_MOTOR)
    out = [
        f"identification ({table.path}, truth: {table.truth_source}, "
        f"t = {table.t0_s:.3f} .. {table.t1_s:.3f} s; convergence: stays within +-{100 * TOL:.0f} %)"
    ]
    if with_paper:
        out.append(
            "  paper: paper A's Table 2 as published (its estimates, their errors against its own "
            "nominal motor, its times)"
        )
    # rows of 79 characters with paper A's columns: an 80-column terminal does not wrap them
    hdr = f"  {'param':<10}{'truth':>10}{'ours':>10}{'error':>10}{'t_conv s':>10}"
    if with_paper:
        hdr += f"  |{'paper':>9}{'error':>9}{'t s':>6}"
    for e in ESTIMATORS:
        if table.cell(e, "l_d_h") is None:
            continue
        out.append(f"{e}:")
        out.append(hdr)
        for p in ("l_d_h", "l_q_h", "r_s_ohm", "psi_f_wb"):
            c = table.cell(e, p)
            assert c is not None  # the estimator has l_d_h, so it has all four
            name, unit, _ = UNITS[p]
            conv = c.conv_text()
            line = (
                f"  {name + ' ' + unit:<10}{_fmt(p, c.truth):>10}{_fmt(p, c.final):>10}"
                f"{100 * c.error_rel:>+9.2f}%{conv:>10}"
            )
            if with_paper:
                v, err, ts = PAPER_A_TABLE2[e][p]
                line += f"  |{_fmt(p, v):>9}{100 * err / PAPER_A_TRUE[p]:>8.2f}%{ts:>6.2f}"
            out.append(line)
    frozen = [
        f"{e} " + ", ".join(names)
        for e in ESTIMATORS
        if (
            names := [
                UNITS[c.param][0] for c in table.cells if c.estimator == e and c.t_first_s is None
            ]
        )
    ]
    if frozen:
        out.append(
            f"never updated (0, never): {'; '.join(frozen)}. The estimators' guards "
            f"(docs/identification.md): L_d only with |mean i_d| >= 1 A (with i_d = 0 or a "
            f"surface motor: a run segment's inject_a), L_q with |mean i_q| >= 0.5 A, none below "
            f"|w_e| 40 rad/s or in segments with estimate: false"
        )
    floored = [
        f"{c.estimator} {UNITS[c.param][0]}"
        for c in table.cells
        if c.t_first_s is not None and c.final == 0.0 and c.truth != 0.0
    ]
    if floored:
        out.append(
            f"at 0 after updating (run to the lower bound): {', '.join(floored)}. A step too large "
            "for this operating point overshoots: Adaline's fixed step is set at 1000 r/min, 5 A "
            "of i_q and 2 A of i_d (docs/identification.md), and LMS diverges once mu |x|^2 / "
            "|x_ref|^2 passes 2, a regressor (w_e i_q on L_q) some 4.5 times the tuning point's; "
            "NLMS-Adaline normalises its step and does not"
        )
    return "\n".join(out)


def convergence_plot(
    path: Path | str, out_png: Path | str, t0_s: float | None = None, t1_s: float | None = None
) -> Path:
    """Per parameter: each estimator against the truth (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    log = read_log(path, topics=IDENT_TOPICS)
    par = log.topic("/pmsm/params")
    t_all = np.asarray(par["t_s"], dtype=float)
    names = _names(par)
    from pmsm_hil.analysis.report_style import legend

    fig, axes = plt.subplots(4, 1, figsize=(11, 10), sharex=True)
    for ax, p in zip(axes, ("l_d_h", "l_q_h", "psi_f_wb", "r_s_ohm"), strict=False):
        name, unit, k = UNITS[p]
        for est in (*ESTIMATORS, "nominal"):
            sel = names == est
            if t0_s is not None:
                sel &= t_all >= t0_s
            if t1_s is not None:
                sel &= t_all <= t1_s
            if np.any(sel):
                ax.plot(
                    t_all[sel],
                    np.asarray(par[p], dtype=float)[sel] * k,
                    label=est,
                    lw=1.0 if est != "nominal" else 0.8,
                    ls="-" if est != "nominal" else ":",
                )
        t = t_all[(t_all >= (t0_s or -1)) & (t_all <= (t1_s if t1_s is not None else 1e9))]
        truth, src = _truth(log, t)
        ax.plot(t, truth[p] * k, "k--", lw=1.0, label=f"truth ({src})")
        tr = truth[p] * k
        if len(tr):
            lo, hi = float(np.min(tr)), float(np.max(tr))
            ax.set_ylim(lo * 0.8, hi * 1.2)
        ax.set_ylabel(f"{name} ({unit})")
        ax.grid(alpha=0.3)
    legend(axes[0])  # to the right of the axes: it covers no estimate
    axes[-1].set_xlabel("device time (s)")
    fig.suptitle(f"online identification: {Path(path).name}")
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png, dpi=110)
    plt.close(fig)
    return out_png
