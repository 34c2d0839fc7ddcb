"""The plant's own mean speed over a window, from the emulator's truth (docs/analysis.md, "true
err"). The truth comes at truth_hz (100 Hz by default): too sparse to average a speed that ripples
at a multiple of that rate (cogging or flux harmonics at 600 Hz are sampled at the same phase every
time: a constant bias of several r/min). The truth's electrical angle at the same instants is not
aliased once it is unwrapped: the mean speed is the angle travelled over the time. The measured
speed (the telemetry, 2 kHz) predicts the angle travelled between two truth instants; the truth's
angles correct the prediction modulo a turn, which holds while the measurement errs by less than
half an electrical turn between two truth frames (some 375 r/min at 100 Hz with four pole
pairs)."""

from __future__ import annotations

import math

import numpy as np

RPM_TO_RAD_S = math.pi / 30.0


def true_speed_correction_rpm(
    t_s: np.ndarray,
    speed_rpm: np.ndarray,
    truth_t_s: np.ndarray,
    truth_theta_e_rad: np.ndarray,
    pole_pairs: int,
) -> float | None:
    """The plant's mean speed minus the measured one (r/min) between the first and the last truth
    instant given (at least two, within the telemetry's span); None when that cannot be told."""
    tt = np.asarray(truth_t_s, dtype=float)
    if len(tt) < 2 or pole_pairs <= 0 or tt[-1] <= tt[0]:
        return None
    t = np.asarray(t_s, dtype=float)
    if len(t) < 2 or tt[0] < t[0] or tt[-1] > t[-1]:
        return None
    w_e = np.asarray(speed_rpm, dtype=float) * RPM_TO_RAD_S * pole_pairs
    # the measured electrical angle travelled since t[0] (trapezoids), at the truth instants
    travelled = np.concatenate(([0.0], np.cumsum(0.5 * (w_e[1:] + w_e[:-1]) * np.diff(t))))
    predicted = np.diff(np.interp(tt, t, travelled))
    seen = np.diff(np.asarray(truth_theta_e_rad, dtype=float))
    residual = np.angle(np.exp(1j * (seen - predicted)))  # wrapped to (-pi, pi]
    return float(np.sum(residual) / (pole_pairs * RPM_TO_RAD_S * (tt[-1] - tt[0])))
