"""Checks of the current controllers' settings across fields: the FOC bandwidth against the
control rate (the firmware refuses a configuration above 0.5/ts_s), and settings of a
controller that no segment runs (they have no effect: a warning)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from ._base import num
from ._source import Problem, Source, fmt_num

if TYPE_CHECKING:
    from .profile import Profile

# the firmware's limit on the FOC current-loop bandwidth: foc_bw_rad_s * ts_s < 0.5
FOC_BW_TS_MAX = 0.5


def segment_controllers(control: dict, segments: list) -> list[str]:
    """The current controller of each segment, from a profile's raw `control` and `segments`
    (its YAML data, or a log's attached profile): the segment's `current_ctrl`, else the previous
    segment's, else `control.current_ctrl` (default mpcc)."""
    first = control.get("current_ctrl")
    ctrl = first if isinstance(first, str) else "mpcc"
    out = []
    for seg in segments:
        own = seg.get("current_ctrl") if isinstance(seg, dict) else None
        ctrl = own if isinstance(own, str) else ctrl
        out.append(ctrl)
    return out


def profile_controllers(profile: Profile) -> list[str]:
    """``segment_controllers`` of a loaded profile."""
    return segment_controllers(
        {"current_ctrl": profile.control.current_ctrl},
        [{"current_ctrl": seg.current_ctrl} for seg in profile.segments],
    )


def _controllers(control: dict, segments: list) -> set[str]:
    """The current controllers the run uses: control.current_ctrl and any segment's choice."""
    return {*segment_controllers(control, [{}]), *segment_controllers(control, segments)}


def control_checks(
    src: Source, control: dict, segments: list, ts_s: float | None
) -> tuple[list[Problem], list[str]]:
    problems: list[Problem] = []
    warnings: list[str] = []
    bw = num(control, "foc_bw_rad_s")
    if bw is not None and bw > 0 and ts_s is not None and ts_s > 0:
        bw_max = FOC_BW_TS_MAX / ts_s
        if bw > bw_max:  # the firmware takes bw <= 0.5/ts_s
            default = 2.0 * math.pi / (20.0 * ts_s)
            problems.append(
                src.problem(
                    ("control", "foc_bw_rad_s"),
                    f"is above 0.5/control.ts_s = {fmt_num(round(bw_max, 3))} rad/s, the "
                    f"most the control rate {fmt_num(round(1.0 / ts_s, 3))} Hz allows (the "
                    f"firmware refuses it); null gives 2 pi/(20 ts_s) = {default:.0f} rad/s",
                    bw,
                )
            )
    used = _controllers(control, segments)
    unused: list[tuple[str, str]] = []
    if "foc" not in used:
        unused += [("foc_bw_rad_s", "foc")]
    if "mpcc" not in used:
        unused += [("rho", "mpcc"), ("mpcc_candidates", "mpcc")]
    for key, ctrl in unused:
        value: Any = control.get(key)
        if value is None or (key == "rho" and value == 1.0):  # rho: 1.0 is the default
            continue
        warnings.append(
            f"{src.path}:{src.line(('control', key))}: control.{key} = {value} has no effect: "
            f"no segment runs {ctrl.upper()} (control.current_ctrl and segments[].current_ctrl)"
        )
    return problems, warnings
