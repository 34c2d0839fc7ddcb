"""Checks of a sensorless profile against its motor file (docs/sensorless.md): an angle source the
motor cannot carry is an error, a start that works on the emulator only is a warning."""

from __future__ import annotations

import math

from ._base import num
from ._source import Problem, Source, fmt_num
from .motor import Motor


def sensorless_checks(
    src: Source, motor: Motor, motor_src: Source
) -> tuple[list[Problem], list[str]]:
    """(problems, warnings) of the profile ``src``'s control.angle_src with ``motor`` (read from
    ``motor_src``)."""
    d = src.data
    control = d.get("control") if isinstance(d.get("control"), dict) else {}
    angle_src = control.get("angle_src", "encoder")
    problems: list[Problem] = []
    warnings: list[str] = []
    salient = motor.flux_map or not math.isclose(motor.l_d_h, motor.l_q_h, rel_tol=1e-6)
    if angle_src in ("ripple_pll", "hybrid") and not salient:
        problems.append(
            src.problem(
                ("control", "angle_src"),
                f"tracks the motor's saliency (L_q != L_d), but {motor.path} has l_d_h = "
                f"l_q_h = {fmt_num(motor.l_d_h)} H and no flux_map: the ripple PLL could "
                "never lock (a surface motor); use mras, with the motor file's "
                "if_start_current_a for a start from standstill",
                angle_src,
            )
        )
    estimator = control.get("estimator") if isinstance(control.get("estimator"), dict) else {}
    min_rpm = num(estimator, "min_speed_rpm")
    if angle_src != "encoder" and min_rpm is not None and min_rpm >= motor.speed_max_rpm:
        problems.append(
            src.problem(
                ("control", "estimator", "min_speed_rpm"),
                f"is not below the motor's speed_max_rpm {fmt_num(motor.speed_max_rpm)} r/min "
                f"({motor.path}): the estimator would never lock; the speed in r/min from "
                "which it may close the loop (null: 5 % of speed_max_rpm)",
                min_rpm,
            )
        )
    if angle_src == "hybrid" and motor.hybrid_mras_on_rpm >= motor.speed_max_rpm:
        key = "hybrid_mras_on_rpm"
        given = key in motor_src.data
        text = (
            f"{'' if given else '(the default) '}is not below the motor's speed_max_rpm "
            f"{fmt_num(motor.speed_max_rpm)} r/min: with control.angle_src hybrid ({src.path}) "
            f"the MRAS would never take the angle over; write less than "
            f"{fmt_num(motor.speed_max_rpm)} (and hybrid_pll_on_rpm below it)"
        )
        problems.append(motor_src.problem((key,), text, motor.hybrid_mras_on_rpm))
    segments = d.get("segments") if isinstance(d.get("segments"), list) else []
    first = segments[0] if segments and isinstance(segments[0], dict) else None
    if (
        angle_src == "mras"
        and first is not None
        and not first.get("angle_encoder")
        and not motor.if_start_current_a
    ):
        warnings.append(
            f"{src.path}:{src.line(('segments', 0))}: segments[0] starts at standstill on the "
            f"MRAS (control.angle_src mras), which sees no back-EMF at rest, and {motor.path} "
            "has no if_start_current_a (an I/f start): on the emulator it starts because the "
            "rotor rests at electrical angle 0, the estimator's default initial angle; on a rig "
            "it depends on where the rotor rests. Start on the encoder (angle_encoder: true) or "
            "give the motor file if_start_current_a (docs/sensorless.md)"
        )
    return problems, warnings
