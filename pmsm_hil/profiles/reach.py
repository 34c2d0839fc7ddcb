"""Can the drive reach each segment's speed at its load on the run's DC link? The steady-state
voltage (Motor.voltage_needed_v) against the linear modulation limit v_dc / sqrt 3 (beyond it: a
warning, only over-modulation gets there) and the six-step limit 2 v_dc / pi (beyond it: no
modulation gets there, an error). The firmware does not weaken the field."""

from __future__ import annotations

import math

from ._base import num
from ._source import Problem, Source, fmt_num
from .motor import Motor
from .rig import Rig


def _reach_rpm(motor: Motor, load_nm: float, limit_v: float, mtpa: bool) -> float:
    """The highest speed at which ``load_nm`` needs at most ``limit_v`` (0 if none)."""
    if motor.voltage_needed_v(0.0, load_nm, mtpa) > limit_v:
        return 0.0
    lo, hi = 0.0, motor.speed_max_rpm
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if motor.voltage_needed_v(mid, load_nm, mtpa) <= limit_v else (lo, mid)
    return lo


def reach_checks(src: Source, motor: Motor, rig: Rig) -> tuple[list[Problem], list[str]]:
    """(problems, warnings) for the run segments the DC link cannot carry at their load."""
    d = src.data
    control = d.get("control") if isinstance(d.get("control"), dict) else {}
    mtpa = control.get("current_ref", "mtpa") != "id_zero"
    v_dc = rig.v_dc_v if rig.v_dc_v is not None else motor.v_dc_v
    where = f"{rig.path}" if rig.v_dc_v is not None else f"{motor.path}"
    linear_v, six_step_v = v_dc / math.sqrt(3.0), 2.0 * v_dc / math.pi
    problems: list[Problem] = []
    warnings: list[str] = []
    segments = d.get("segments") if isinstance(d.get("segments"), list) else []
    for i, seg in enumerate(segments):
        if not isinstance(seg, dict) or seg.get("kind", "run") != "run":
            continue
        v, load = num(seg, "speed_rpm"), num(seg, "load_nm", 0.0)
        if v is None or load is None or abs(v) > motor.speed_max_rpm * (1 + 1e-12):
            continue  # reported elsewhere
        need_v = motor.voltage_needed_v(v, load, mtpa)
        if need_v <= linear_v * 1.001:
            continue
        reach = _reach_rpm(motor, load, linear_v, mtpa)
        text = (
            f"with load_nm {fmt_num(load)} needs {need_v:.4g} V peak phase (steady state, the "
            f"motor file's r_s_ohm, l_d_h, l_q_h, psi_f_wb) but v_dc_v {fmt_num(v_dc)} V "
            f"({where}) gives {linear_v:.4g} V (v_dc_v / sqrt 3) without over-modulation and "
            f"{six_step_v:.4g} V (2 v_dc_v / pi) at most: "
            f"{'write ' + str(math.floor(reach)) + ' r/min or less' if reach > 0 else 'lower load_nm'}"
        )
        if need_v > six_step_v:
            hint = (
                "; or check r_s_ohm (ohm, not mohm), l_d_h, l_q_h (H, not mH) and psi_f_wb "
                "(Wb) in the motor file"
            )
            problems.append(src.problem(("segments", i, "speed_rpm"), text + hint, v))
        else:
            line = src.line(("segments", i, "speed_rpm"))
            warnings.append(
                f"{src.path}:{line}: segments[{i}].speed_rpm = {fmt_num(v)} {text} "
                f"(the current controller over-modulates; FOC stops at v_dc_v / sqrt 3)"
            )
    return problems, warnings
