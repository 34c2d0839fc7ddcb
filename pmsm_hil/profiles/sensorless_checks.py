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
    if angle_src in ("ripple_pll", "hybrid") and salient and not motor.flux_map and segments:
        warnings.append(
            f"{src.path}:{src.line(('control', 'angle_src'))}: control.angle_src {angle_src} "
            "starts with the polarity test, which compares the d axis's saturation with the "
            f"motor's own signature, and {motor.path} has no flux_map: the firmware assumes "
            "that positive i_d saturates first. On the emulator that start fails whatever the "
            "first segment (the test runs beside the encoder too): a rig without the saturation "
            "effect (default) does not saturate (polarity not resolved, lost_lock), and "
            "lab-typical's saturation (paper A's map) is larger on the negative side (the wrong "
            "pole: the drive runs away); on a rig it holds only if its iron saturates that way. Give "
            "the motor file its flux_map (pmsm-hil commission --flux-map measures one; "
            "docs/sensorless.md, 'Polarity at start-up')"
        )
    if (
        angle_src == "mras"
        and first is not None
        and not first.get("angle_encoder")
        and not motor.if_start_current_a
    ):
        warnings.append(
            f"{src.path}:{src.line(('segments', 0))}: segments[0] starts at standstill on the "
            f"MRAS (control.angle_src mras), which sees no back-EMF at rest, and {motor.path} "
            "has no if_start_current_a (an I/f start): on the emulator it may start, as the "
            "rotor rests at electrical angle 0, the estimator's default initial angle, if the "
            "speed passes min_speed_rpm within estimator.lock_timeout_s; on a rig it also "
            "depends on where the rotor rests. Start on the encoder (angle_encoder: true) or "
            "give the motor file if_start_current_a (docs/sensorless.md)"
        )
    if angle_src == "mras":
        warnings += _mras_below_range(src, segments, min_rpm, motor)
    return problems, warnings


def _mras_below_range(
    src: Source, segments: list, min_rpm: float | None, motor: Motor
) -> list[str]:
    """Warnings for segments on the MRAS whose speed reference goes below the estimator's
    minimum speed or through zero after the start (the MRAS loses lock there: lost_lock)."""
    w_min = min_rpm if min_rpm is not None else 0.05 * motor.speed_max_rpm
    out: list[str] = []
    speed = 0.0
    for i, seg in enumerate(segments):
        if not isinstance(seg, dict):
            return out
        v, dur, ramp = num(seg, "speed_rpm"), num(seg, "duration_s"), num(seg, "ramp_rpm_s")
        if v is None or dur is None or dur <= 0:
            return out
        end = v
        if ramp is not None and ramp > 0 and abs(v - speed) > ramp * dur:
            end = speed + math.copysign(ramp * dur, v - speed)
        low = min(abs(end), abs(speed) if i else abs(end))
        through = i > 0 and speed * end < 0
        if not seg.get("angle_encoder") and (low < w_min or through):
            what = "reverses through 0" if through else f"goes to {end:.4g}"
            out.append(
                f"{src.path}:{src.line(('segments', i))}: segments[{i}] {what} r/min on the "
                f"MRAS (control.angle_src mras), below its minimum speed {fmt_num(w_min)} "
                "r/min (estimator.min_speed_rpm; null: 5 % of speed_max_rpm), where it sees "
                "too little back-EMF: it loses lock there and the drive trips lost_lock. Run "
                "that segment on the encoder (angle_encoder: true) (docs/sensorless.md)"
            )
        speed = end
    return out
