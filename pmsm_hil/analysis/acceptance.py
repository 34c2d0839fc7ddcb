"""A run judged against its profile's acceptance criteria: one check per bound and segment, with
the measured value beside the bound (the run summary and the identification table measure)."""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from os import PathLike

    from pmsm_hil.analysis.identification import IdentTable
    from pmsm_hil.analysis.summary import RunSummary
    from pmsm_hil.log.reader import Log
    from pmsm_hil.profiles import Profile
    from pmsm_hil.profiles.acceptance import Acceptance
    from pmsm_hil.profiles.current_step import CurrentStep

__all__ = [
    "Check",
    "acceptance_line",
    "checks_failed",
    "evaluate",
    "hints",
    "profile_checks",
    "ripple_hint",
]


@dataclass
class Check:
    scope: str  # "run", or "segment 3 '240 r/min load on'"
    criterion: str  # "speed error", "recovery", "faults", "nlms_adaline l_q_h error", ...
    measured: str  # the measured value with its unit (or "not seen")
    bound: str  # the bound with its unit
    passed: bool

    def as_dict(self) -> dict:
        return asdict(self)


def _seg_scope(s) -> str:
    return f"segment {s.index} {s.name!r}"


def _num(v: float, unit: str, bound: float, sign: bool = False) -> str:
    """A measured value to the bound's resolution and two digits finer (at least 3 decimals): a
    speed error of 3e-05 r/min beside a bound of 0.0001 reads +0.000030, not +0.000."""
    d = max(3, 2 - math.floor(math.log10(bound))) if bound > 0 else 3
    return f"{v:+.{d}f} {unit}" if sign else f"{v:.{d}f} {unit}"


def _not_judged(s) -> str:
    if math.isnan(s.mean_error_rpm):
        return "not judged: too short to measure"
    return f"not judged: a ramp (at its set-point {s.plateau_s:.3g} s)"


BOUND_KEYS = ("speed_error_max_rpm", "ripple_d_max_a", "ripple_q_max_a", "recovery_max_s", "faults")


def _segment_checks(bounds, segs, scope_all: bool, skip=frozenset()) -> list[Check]:
    """The checks of ``bounds`` on ``segs``: run-wide (``scope_all``: the plateaus at a non-zero
    set-point, the load steps there; the (segment index, bound key) pairs in ``skip`` are left to
    a segment's own bounds) or one segment's own (every bound it gives is checked, and fails
    when it cannot be measured)."""
    out: list[Check] = []
    for s in segs:
        scope = _seg_scope(s)
        plateau = (s.setpoint_rpm != 0 and s.mean_judged) or not scope_all

        def given(key: str, s=s) -> Any:
            return None if (s.index, key) in skip else getattr(bounds, key)

        b = given("speed_error_max_rpm")
        if b is not None and plateau:
            lim = s.band_rpm if b == "band" else float(b)
            err = s.mean_error_rpm
            out.append(
                Check(
                    scope,
                    "speed error",
                    _num(err, "r/min", lim, sign=True) if s.mean_judged else _not_judged(s),
                    f"|.| <= {lim:.4g} r/min" + (" (band)" if b == "band" else ""),
                    bool(s.mean_judged and not math.isnan(err) and abs(err) <= lim),
                )
            )
        for key, name in (("ripple_d_max_a", "ripple i_d"), ("ripple_q_max_a", "ripple i_q")):
            lim = given(key)
            if lim is not None and plateau:
                v = s.ripple_d_a if key == "ripple_d_max_a" else s.ripple_q_a
                out.append(
                    Check(
                        scope,
                        name,
                        _num(v, "A", lim) if s.mean_judged else _not_judged(s),
                        f"<= {lim:g} A",
                        bool(s.mean_judged and not math.isnan(v) and v <= lim),
                    )
                )
        lim = given("recovery_max_s")
        if lim is not None and (not scope_all or (s.recovery_s is not None and plateau)):
            v = s.recovery_s
            shown = (
                "no load step" if v is None else ("never" if math.isinf(v) else _num(v, "s", lim))
            )
            out.append(Check(scope, "recovery", shown, f"<= {lim:g} s", v is not None and v <= lim))
        if given("faults") is not None and not scope_all:
            out.append(_fault_check(scope, s.faults, bounds.faults))
    return out


def _fault_check(scope: str, n: int, rule: str, names: list[str] | None = None) -> Check:
    ok = n == 0 if rule == "forbidden" else n > 0
    shown = str(n) + (
        f" ({'; '.join(names[:3])}{'; ...' if len(names) > 3 else ''})" if names else ""
    )
    return Check(scope, "faults", shown, "none" if rule == "forbidden" else ">= 1 (expected)", ok)


def _segments_bounded(acceptance: Acceptance, summary: RunSummary) -> list[tuple[Any, Any]]:
    """(a segment's own bounds, the segment's stats, or None when the log never shows it)."""
    by_index = {s.index: s for s in summary.segments}
    by_name = {s.name: s for s in summary.segments}
    return [
        (sa, by_index.get(sa.segment) if isinstance(sa.segment, int) else by_name.get(sa.segment))
        for sa in acceptance.segments
    ]


def evaluate(
    acceptance: Acceptance | None, summary: RunSummary, ident: IdentTable | None = None
) -> list[Check]:
    """The checks of ``acceptance`` (a profile's Acceptance) on a run's RunSummary and, for
    identification bounds, its IdentTable (None: those checks fail as not measured). Without a
    `run:` section the run-wide defaults hold (the whole profile played, no fault)."""
    from pmsm_hil.profiles.acceptance import RunAcceptance

    out: list[Check] = []
    if acceptance is None:
        return out
    run = acceptance.run if acceptance.run is not None else RunAcceptance()
    if run.complete:
        out.append(
            Check(
                "run",
                "complete",
                "yes" if summary.complete else f"no ({summary.ended or 'the log ends early'})",
                "whole profile",
                summary.complete,
            )
        )
    if run.faults != "ignored":
        names = [f.split(" s ", 1)[-1] for f in summary.faults]
        out.append(_fault_check("run", len(summary.faults), run.faults, names))
    bounded = _segments_bounded(acceptance, summary)
    # a segment's own bound replaces the run-wide one there (it loosens or tightens it)
    own = {
        (seg.index, k)
        for sa, seg in bounded
        if seg is not None
        for k in BOUND_KEYS
        if getattr(sa, k) is not None
    }
    out += _segment_checks(run, summary.segments, scope_all=True, skip=own)
    out += _angle_checks(run, summary)
    out += _ident_checks(run, ident)
    for sa, seg in bounded:
        if seg is None:
            out.append(
                Check(f"segment {sa.segment!r}", "seen", "not seen in the log", "played", False)
            )
            continue
        out += _segment_checks(sa, [seg], scope_all=False)
    return sorted(out, key=_order)


def _order(c: Check) -> tuple[int, int]:
    """The run's checks first, then each segment's, run-wide and its own bounds together."""
    if c.scope == "run":
        return (0, 0)
    m = re.match(r"segment (\d+) ", c.scope)
    return (1, int(m.group(1))) if m else (2, 0)


def _ident_checks(run, ident: IdentTable | None) -> list[Check]:
    out: list[Check] = []
    for ib in run.identification:
        cell = ident.cell(ib.estimator, ib.param) if ident is not None else None
        what = f"{ib.estimator} {ib.param}"
        if ib.error_max_rel is not None:
            if cell is None:
                out.append(
                    Check(
                        "run",
                        f"{what} error",
                        "not measured",
                        f"<= {100 * ib.error_max_rel:g} %",
                        False,
                    )
                )
            else:
                e = cell.error_rel
                out.append(
                    Check(
                        "run",
                        f"{what} error",
                        f"{100 * e:+.2f} %",
                        f"|.| <= {100 * ib.error_max_rel:g} %",
                        bool(not math.isnan(e) and abs(e) <= ib.error_max_rel),
                    )
                )
        if ib.conv_max_s is not None:
            c = None if cell is None else cell.conv_s
            out.append(
                Check(
                    "run",
                    f"{what} convergence",
                    "not measured" if cell is None else ("never" if c is None else f"{c:.3f} s"),
                    f"<= {ib.conv_max_s:g} s",
                    c is not None and c <= ib.conv_max_s,
                )
            )
    return out


def _angle_checks(run, summary: RunSummary) -> list[Check]:
    """The angle estimator's error against the encoder while it closed the loop (the run
    summary's estimator figures); not measured (a failed check) when no estimator closed it."""
    out: list[Check] = []
    e = summary.estimator or {}
    for key, stat, name in (
        ("angle_error_rms_max_rad", "theta_err_rms_rad", "angle error RMS"),
        ("angle_error_max_rad", "theta_err_max_rad", "largest angle error"),
    ):
        lim = getattr(run, key)
        if lim is None:
            continue
        v = e.get(stat)
        out.append(
            Check(
                "run",
                name,
                "not measured (no estimator closed the loop)" if v is None else f"{v:.4f} rad",
                f"<= {lim:g} rad",
                v is not None and v <= lim,
            )
        )
    return out


def profile_checks(
    profile: Profile,
    log_path: str | PathLike,
    summary: RunSummary,
    log: Log | None = None,
    table: IdentTable | None = None,
) -> list[Check] | None:
    """The checks of a profile's acceptance criteria on its run (the identification table over the
    profile's identification window, as `pmsm-hil test` takes it; ``table``: that table when the
    caller has made it already); None without criteria."""
    from pathlib import Path

    acc = getattr(profile, "acceptance", None)
    if acc is None:
        return None
    if (
        table is None
        and acc.run is not None
        and acc.run.identification
        and getattr(profile.control, "identify", False)
    ):
        from pmsm_hil.analysis.identification import identification_table, identification_window

        t0, t1 = identification_window(profile)
        table = identification_table(Path(log_path), t0, t1, log=log)
    return evaluate(acc, summary, table)


def acceptance_line(checks: list[Check], most: int = 3) -> str:
    """One line for the end of a run: how many of the profile's criteria passed, the failed ones
    with the measured value beside the bound."""
    bad = [c for c in checks if not c.passed]
    head = f"acceptance (the profile's criteria): {len(checks) - len(bad)} of {len(checks)} checks passed"
    if not bad:
        return head
    shown = [f"{c.scope} {c.criterion} {c.measured} ({c.bound})" for c in bad[:most]]
    if len(bad) > most:
        shown.append(f"and {len(bad) - most} more (`pmsm-hil test` for the table)")
    return f"{head}; failed: {'; '.join(shown)}"


def checks_failed(checks: list[Check]) -> int:
    return sum(1 for c in checks if not c.passed)


def commission_hint(failed: list[str], motor_yaml: str, rig_yaml: str) -> str | None:
    """When identification criteria (``failed``: the failed checks' criteria) missed with a
    motor file that is not commissioned, on a rig with what commissioning measures and the motor
    file does not say: what that is, and the commands that remove it (docs/sweep.md)."""
    import yaml

    from pmsm_hil.analysis.identification import ESTIMATORS

    if not any(c.split(" ")[0] in ESTIMATORS for c in failed):
        return None
    motor = yaml.safe_load(motor_yaml or "") or {}
    rig = yaml.safe_load(rig_yaml or "") or {}
    if motor.get("commissioning"):
        return None
    on = {
        n: e
        for n, e in (rig.get("effects") or {}).items()
        if isinstance(e, dict) and e.get("enabled", True) is not False
    }
    unknown = []
    if on.get("encoder", {}).get("offset_e_rad", 0.0):
        unknown.append("encoder offset")
    if "sensor_offset" in on or "sensor_gain" in on:
        unknown.append("current-sensor offsets and gains")
    dt = on.get("dead_time")
    if dt is not None and (
        dt.get("dead_time_s", 2e-6) != motor.get("dead_time_s", 0.0)
        or dt.get("v_drop_v", 1.0) != motor.get("v_drop_v", 0.0)
    ):
        unknown.append("inverter dead time and drop")
    if "motor_deviation" in on:
        unknown.append("the motor's own R, L, psi_f")
    if not unknown:
        return None
    name = rig.get("name", "RIG")
    return (
        f"the motor file is not commissioned, and rig {name} has what commissioning measures and "
        f"the firmware is not told ({', '.join(unknown)}); the identification is judged against "
        f"the plant. Commission first (pmsm-hil commission --rig {name} -o commissioned.yaml) "
        "and run with --motor commissioned.yaml"
    )


# the criteria that the MPCC's current ripple can make a plateau miss
_RIPPLE_MISSES = ("speed error", "recovery", "ripple i_d", "ripple i_q")
_SCOPE_INDEX = re.compile(r"segment (\d+) ")


def ripple_hint(checks: list[Check], step: CurrentStep) -> str | None:
    """When speed, recovery or current-ripple criteria missed on segments that run the MPCC and
    its current step over one control period is a large share of i_max_a (a motor of low
    inductance for the control period): the step and what suits such a motor."""
    from pmsm_hil.profiles.current_step import STEP_SHARE_HINT

    missed = sorted(
        {
            int(m.group(1))
            for c in checks
            if not c.passed
            and c.criterion in _RIPPLE_MISSES
            and (m := _SCOPE_INDEX.match(c.scope)) is not None
            and int(m.group(1)) in step.mpcc_segments
        }
    )
    if not missed or step.share < STEP_SHARE_HINT:
        return None
    which = ", ".join(str(i) for i in missed)
    return (
        f"segment{'s' if len(missed) > 1 else ''} {which} ran the MPCC, whose current step over "
        f"one control period (2/3 v_dc ts_s / min(L_d, L_q) = 2/3 x {step.v_dc_v:g} V x "
        f"{step.ts_s * 1e6:g} us / {step.l_min_h * 1e3:.4g} mH) is {step.step_a:.3g} A, "
        f"{100 * step.share:.0f} % of i_max_a {step.i_max_a:g} A: its current ripple shakes the "
        "speed, most at low speed. A motor of such low inductance for this period wants FOC "
        "(control.current_ctrl: foc); a shorter control.ts_s helps less (docs/control.md, "
        '"A motor of low inductance")'
    )


def hints(
    checks: list[Check], motor_yaml: str, rig_yaml: str, step: CurrentStep | None
) -> list[str]:
    """What a run's missed criteria point to (commission_hint, ripple_hint), as `run` and `test`
    print them under their verdicts."""
    failed = [c.criterion for c in checks if not c.passed]
    out = [commission_hint(failed, motor_yaml, rig_yaml)]
    if step is not None:
        out.append(ripple_hint(checks, step))
    return [h for h in out if h]
