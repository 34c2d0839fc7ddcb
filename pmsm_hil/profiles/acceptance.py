"""Acceptance criteria of a profile (the optional `acceptance:` section): bounds that a run must
meet for `pmsm-hil test` to pass it. They are read and validated with the profile and change
nothing on the device.

    acceptance:
      run:                          # every plateau / load step / the whole run
        complete: true              # the log shows every segment to the profile's end (default)
        faults: forbidden           # forbidden (default) | expected | ignored
        speed_error_max_rpm: band   # |mean speed error| on every plateau; `band` = max(1 %, 1 r/min)
        ripple_q_max_a: 1.5         # RMS of i_q - i_q* on every plateau
        recovery_max_s: 0.3         # every load step on a plateau
        identification:
          - {estimator: nlms_adaline, param: l_q_h, error_max_rel: 0.02, conv_max_s: 0.5}
      segments:                     # one segment, by name or index
        - {segment: "1000 r/min load on", recovery_max_s: 0.2}

The measured quantities are those of the run summary and the identification table
(docs/analysis.md, docs/identification.md); the format is in docs/profiles.md.
"""

from __future__ import annotations

import re
from typing import Annotated, Literal

from pydantic import Field

from pmsm_hil.names import did_you_mean

from ._base import StrictModel
from ._source import Problem, Source

__all__ = [
    "ESTIMATORS",
    "PARAMS",
    "Acceptance",
    "IdentBound",
    "RunAcceptance",
    "SegmentAcceptance",
    "acceptance_problems",
]

ESTIMATORS = ("rls", "adaline", "nlms_adaline")
PARAMS = ("l_d_h", "l_q_h", "psi_f_wb", "r_s_ohm")


class Bounds(StrictModel):
    speed_error_max_rpm: Annotated[float, Field(gt=0)] | Literal["band"] | None = Field(
        None,
        description="largest |mean speed error| on a plateau, r/min, or `band`: max(1 %, 1 r/min)",
    )
    ripple_d_max_a: float | None = Field(
        None, gt=0, description="largest RMS of i_d - i_d* on a plateau, A"
    )
    ripple_q_max_a: float | None = Field(
        None, gt=0, description="largest RMS of i_q - i_q* on a plateau, A"
    )
    recovery_max_s: float | None = Field(
        None, gt=0, description="longest recovery after a load step, s"
    )
    faults: Literal["forbidden", "expected"] | None = Field(
        None, description="forbidden: no fault in the segment; expected: at least one"
    )


class IdentBound(StrictModel):
    estimator: Literal[ESTIMATORS] = Field(description="rls, adaline or nlms_adaline")  # type: ignore[valid-type]
    param: Literal[PARAMS] = Field(description="l_d_h, l_q_h, psi_f_wb or r_s_ohm")  # type: ignore[valid-type]
    error_max_rel: float | None = Field(
        None, gt=0, le=10, description="largest |final - truth| / truth (0.02 = 2 %)"
    )
    conv_max_s: float | None = Field(
        None, gt=0, le=3600, description="longest convergence time from the first update, s"
    )


class RunAcceptance(Bounds):
    complete: bool = Field(True, description="the log shows the whole profile played to its end")
    faults: Literal["forbidden", "expected", "ignored"] = Field(  # type: ignore[assignment]
        "forbidden",
        description="forbidden (default): no fault in the run; expected: at least one; "
        "ignored: not checked",
    )
    identification: list[IdentBound] = Field(
        default_factory=list, description="bounds on the identification table"
    )
    angle_error_rms_max_rad: float | None = Field(
        None,
        gt=0,
        le=3.2,
        description="the angle estimator closing the loop: largest RMS of its angle error "
        "against the encoder (theta_err_rad) over the time it closed the loop, rad",
    )
    angle_error_max_rad: float | None = Field(
        None,
        gt=0,
        le=3.2,
        description="the angle estimator closing the loop: largest |theta_err_rad| over that "
        "time, rad",
    )


class SegmentAcceptance(Bounds):
    segment: str | int = Field(description="the segment's name or index")


class Acceptance(StrictModel):
    run: RunAcceptance | None = Field(None, description="bounds on every plateau and the whole run")
    segments: list[SegmentAcceptance] = Field(
        default_factory=list, description="bounds on one segment"
    )


def acceptance_problems(src: Source) -> list[Problem]:
    """Cross-checks on the raw data: each `segment:` names a segment of the profile, a bound is
    given at all, and no segment's bound twice (by its name and its index, say)."""
    d = src.data
    acc = d.get("acceptance")
    if not isinstance(acc, dict):
        return []
    segs = d.get("segments") if isinstance(d.get("segments"), list) else []
    names = [s.get("name") for s in segs if isinstance(s, dict)]
    out: list[Problem] = []
    raw_items = acc.get("segments")
    items: list = raw_items if isinstance(raw_items, list) else []
    given: dict[tuple[int, str], int] = {}  # (segment index, bound) -> the item that gave it
    for i, item in enumerate(items):
        if not isinstance(item, dict):
            continue
        ref = item.get("segment")
        loc = ("acceptance", "segments", i, "segment")
        if isinstance(ref, bool):
            continue
        one = isinstance(ref, str) and names.count(ref) == 1
        index = ref if isinstance(ref, int) else (names.index(ref) if one else -1)
        for k in Bounds.model_fields if 0 <= index < len(segs) else ():
            if item.get(k) is None:
                continue
            if (index, k) in given:  # two bounds on one quantity: which one judges is a guess
                first = f"acceptance.segments[{given[index, k]}]"
                out.append(
                    src.problem(
                        ("acceptance", "segments", i, k),
                        f"bounds segment {index} again ({first} bounds it already): give each "
                        "bound of a segment once",
                        item[k],
                    )
                )
            given.setdefault((index, k), i)
        if isinstance(ref, int) and not 0 <= ref < len(segs):
            out.append(
                src.problem(
                    loc,
                    f"is not a segment index (the profile has {len(segs)}: 0..{len(segs) - 1})",
                    ref,
                )
            )
        elif isinstance(ref, str) and ref not in names:
            m = re.fullmatch(r"segment (\d+)", ref.strip())
            if m and int(m.group(1)) < len(segs) and not names[int(m.group(1))]:
                hint = f"; an unnamed segment is given by its index: segment: {m.group(1)}"
            else:
                hint = did_you_mean(ref, [n for n in names if isinstance(n, str)])
            out.append(src.problem(loc, "names no segment of the profile" + hint, ref))
        elif isinstance(ref, str) and names.count(ref) > 1:
            out.append(src.problem(loc, "names more than one segment: give its index", ref))
        bounds = [k for k in Bounds.model_fields if item.get(k) is not None]
        if not bounds and "segment" in item:
            out.append(
                src.problem(
                    ("acceptance", "segments", i),
                    "gives no bound (known: " + ", ".join(Bounds.model_fields) + ")",
                )
            )
    raw_run = acc.get("run")
    run: dict = raw_run if isinstance(raw_run, dict) else {}
    if (
        run.get("complete") is False
        and run.get("faults") == "ignored"
        and not any(
            run.get(k) is not None
            for k in RunAcceptance.model_fields
            if k not in ("complete", "faults")
        )
        and not items
    ):
        out.append(
            src.problem(
                ("acceptance", "run"),
                "checks nothing (complete: false, faults: ignored and no bound): a run would pass "
                "whatever it did",
            )
        )
    ident = run.get("identification")
    raw_control = d.get("control")
    control: dict = raw_control if isinstance(raw_control, dict) else {}
    if isinstance(ident, list) and ident and not control.get("identify"):
        out.append(
            src.problem(
                ("acceptance", "run", "identification"),
                "bounds the identification, but the profile does not identify "
                "(control.identify is not true): nothing would be measured",
            )
        )
    bounded: dict[tuple, int] = {}  # (estimator, param, bound) -> the item that gave it
    for i, item in enumerate(ident if isinstance(ident, list) else []):
        for k in ("error_max_rel", "conv_max_s"):
            if not isinstance(item, dict) or item.get(k) is None:
                continue
            key = (str(item.get("estimator")), str(item.get("param")), k)
            if key in bounded:
                first = f"acceptance.run.identification[{bounded[key]}]"
                out.append(
                    src.problem(
                        ("acceptance", "run", "identification", i, k),
                        f"bounds {key[0]} {key[1]} again ({first} bounds it already): give each "
                        "bound once",
                        item[k],
                    )
                )
            bounded.setdefault(key, i)
        if (
            isinstance(item, dict)
            and item.get("error_max_rel") is None
            and item.get("conv_max_s") is None
        ):
            out.append(
                src.problem(
                    ("acceptance", "run", "identification", i),
                    "gives no bound (error_max_rel, conv_max_s)",
                )
            )
    return out
