"""The metrics of one run, as flat columns, from its log (summary and identification table).

Column names carry their units. Per segment (index i, from the run summary, docs/analysis.md):
``seg{i}_speed_error_rpm`` (mean error on the plateau window), ``seg{i}_ripple_d_a``/``_q_a``,
``seg{i}_recovery_s`` (load steps only). Whole run: ``speed_error_max_rpm``,
``ripple_d_max_a``, ``ripple_q_max_a``, ``recovery_max_s``: the largest magnitude of the
segment columns of the same name over every segment (standstill segments included: a rotor that
creeps during the R injection is a speed error), so a ``_max`` is never below one of its parts;
``speed_error_max_at_speed_rpm``: the same over the segments at a non-zero setpoint only (what an
``acceptance: run: speed_error_max_rpm`` bound is checked on, docs/profiles.md);
``faults``, ``complete``; the angle estimator closing the loop, against the
encoder (NaN when none did): ``angle_err_mean_rad``, ``angle_err_rms_rad``, ``angle_err_max_rad``.
Identification (per estimator and parameter, from the
start to the first plant step, or the whole run): ``id_{estimator}_{param}_error_rel`` and
``id_{estimator}_{param}_conv_s`` (NaN: never converged).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pmsm_hil.analysis.identification import IdentTable
    from pmsm_hil.analysis.summary import RunSummary
    from pmsm_hil.profiles import Profile

from pmsm_hil.analysis.identification import identification_window

__all__ = ["identification_window", "run_metrics"]

NAN = float("nan")


def _num(x: Any) -> float:
    return NAN if x is None else float(x)


def _max_abs(xs: list[float]) -> float:
    xs = [abs(x) for x in xs if x is not None and not math.isnan(x)]
    return max(xs) if xs else NAN


def summary_metrics(summary: RunSummary, metrics: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    segs = summary.segments
    if "speed_error" in metrics:
        for s in segs:
            out[f"seg{s.index}_speed_error_rpm"] = s.mean_error_rpm
        out["speed_error_max_rpm"] = _max_abs([s.mean_error_rpm for s in segs])
        out["speed_error_max_at_speed_rpm"] = _max_abs(
            [s.mean_error_rpm for s in segs if s.setpoint_rpm != 0]
        )
    if "ripple" in metrics:
        for s in segs:
            out[f"seg{s.index}_ripple_d_a"] = s.ripple_d_a
            out[f"seg{s.index}_ripple_q_a"] = s.ripple_q_a
        out["ripple_d_max_a"] = _max_abs([s.ripple_d_a for s in segs])
        out["ripple_q_max_a"] = _max_abs([s.ripple_q_a for s in segs])
    if "recovery" in metrics:
        steps = [s for s in summary.segments if s.recovery_s is not None]
        for s in steps:
            out[f"seg{s.index}_recovery_s"] = s.recovery_s
        out["recovery_max_s"] = _max_abs([s.recovery_s for s in steps if s.recovery_s is not None])
    if "faults" in metrics:
        out["faults"] = len(summary.faults)
    if "completeness" in metrics:
        out["complete"] = bool(summary.complete)
    if "angle" in metrics:
        e = summary.estimator or {}
        out["angle_err_mean_rad"] = _num(e.get("theta_err_mean_rad"))
        out["angle_err_rms_rad"] = _num(e.get("theta_err_rms_rad"))
        out["angle_err_max_rad"] = _num(e.get("theta_err_max_rad"))
    return out


def ident_metrics(table: IdentTable) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for c in table.cells:
        out[f"id_{c.estimator}_{c.param}_error_rel"] = float(c.error_rel)
        out[f"id_{c.estimator}_{c.param}_conv_s"] = _num(c.conv_s)
    return out


def run_metrics(log_path: str | Path, profile: Profile, metrics: list[str]) -> dict[str, Any]:
    """The chosen metrics of the run logged at ``log_path`` (of ``profile``) and, when the profile
    has acceptance criteria, ``acceptance_failed`` (the number of checks failed) and
    ``acceptance_checks`` (every check, as JSON)."""
    import json

    from pmsm_hil.analysis.reading import read_for_analysis
    from pmsm_hil.analysis.summary import summarize_log

    log = read_for_analysis(log_path)
    summary = summarize_log(Path(log_path), log)
    out = summary_metrics(summary, metrics)
    table = None
    if "identification" in metrics and getattr(profile.control, "identify", False):
        from pmsm_hil.analysis.identification import identification_table

        t0, t1 = identification_window(profile)
        table = identification_table(Path(log_path), t0, t1, log=log)
        out.update(ident_metrics(table))
    from pmsm_hil.analysis.acceptance import checks_failed, profile_checks

    checks = profile_checks(profile, log_path, summary, log, table=table)
    if checks is not None:
        out["acceptance_failed"] = checks_failed(checks)
        out["acceptance_checks"] = json.dumps([c.as_dict() for c in checks])
    return out
