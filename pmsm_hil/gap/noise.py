"""The noise floor: the residual MSE a perfect model would leave (docs/gap.md, "Noise floor").

From the sensor specification (current noise and ADC step per channel, encoder lines) propagated
through the probe, or, where none is given (an imported CSV), estimated from the data: the
measurement noise of i(k+1) and i(k) enters the one-step residual as a first difference, whose
lag-1 autocovariance is minus half its variance, so floor = -2 acov1 of the (augmented) residual.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.gap.model import rot

if TYPE_CHECKING:
    from pmsm_hil.gap.probe import Probe


def floor_from_spec(probe: Probe, spec: dict[str, float]) -> np.ndarray | None:
    """Floor per transition (V^2, mean of the d and q components), or None without a spec."""
    if "i_noise_a" not in spec and "adc_lsb_a" not in spec:
        return None
    m, ts = probe.m, probe.ts_s
    var = spec.get("i_noise_a", 0.0) ** 2 + spec.get("adc_lsb_a", 0.0) ** 2 / 12.0
    k = probe.idx
    rec = probe.rec
    cab = var * np.array([[1.0, 1 / np.sqrt(3.0)], [1 / np.sqrt(3.0), 5.0 / 3.0]])

    def var_dq(th):
        c, s = np.cos(th), np.sin(th)
        vd = c * c * cab[0, 0] + 2 * c * s * cab[0, 1] + s * s * cab[1, 1]
        vq = s * s * cab[0, 0] - 2 * c * s * cab[0, 1] + c * c * cab[1, 1]
        return vd, vq

    vd0, vq0 = var_dq(rec.theta_e_rad[k])
    vd1, vq1 = var_dq(rec.theta_e_rad[k + 1])
    fd = (m.l_d_h / ts) ** 2 * (vd0 + vd1)
    fq = (m.l_q_h / ts) ** 2 * (vq0 + vq1)
    lines = spec.get("encoder_lines", 0.0)
    if lines:
        q2 = (2 * np.pi * m.pole_pairs / (4 * lines)) ** 2 / 12.0
        i_dq = rot(
            np.stack([rec.i_abc[k, 0], (rec.i_abc[k, 0] + 2 * rec.i_abc[k, 1]) / np.sqrt(3.0)], 1),
            -rec.theta_e_rad[k],
        )
        u2 = np.sum(probe._u0[k] ** 2, axis=1)
        fd = fd + (m.l_d_h / ts) ** 2 * 2 * i_dq[:, 1] ** 2 * q2 + u2 * q2 / 2
        fq = fq + (m.l_q_h / ts) ** 2 * 2 * i_dq[:, 0] ** 2 * q2 + u2 * q2 / 2
    return (fd + fq) / 2.0


def floor_from_data(r: np.ndarray, k: np.ndarray) -> float:
    """-2 x the lag-1 autocovariance of the residual (consecutive transitions only), V^2."""
    nxt = np.nonzero(np.diff(k) == 1)[0]
    if len(nxt) < 10:
        return 0.0
    a = r - r.mean(axis=0)
    ac1 = float(np.mean(np.sum(a[nxt] * a[nxt + 1], axis=1)) / 2.0)
    return max(-2.0 * ac1, 0.0)
