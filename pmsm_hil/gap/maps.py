"""Where the gap lies: residual RMS binned by operating point and angle, an order spectrum against
speed (docs/gap.md, "Where")."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.gap.model import abc_to_ab, rot

if TYPE_CHECKING:
    from pmsm_hil.gap.probe import Probe


def _binned(x, r, edges):
    out = []
    b = np.digitize(x, edges[1:-1])
    for j in range(len(edges) - 1):
        s = b == j
        out.append(
            {
                "lo": float(edges[j]),
                "hi": float(edges[j + 1]),
                "n": int(s.sum()),
                "rms_d_v": float(np.sqrt(np.mean(r[s, 0] ** 2))) if s.any() else None,
                "rms_q_v": float(np.sqrt(np.mean(r[s, 1] ** 2))) if s.any() else None,
            }
        )
    return out


def order_spectrum(
    theta: np.ndarray,
    r: np.ndarray,
    speed: np.ndarray,
    orders: Iterable[int] = range(1, 13),
    n_speed: int = 4,
) -> list[dict[str, object]]:
    """Amplitude of the residual's n-th electrical-angle harmonic (V), per speed quartile."""
    edges = np.quantile(speed, np.linspace(0, 1, n_speed + 1))
    rows = []
    for j in range(n_speed):
        s = (speed >= edges[j]) & (speed <= edges[j + 1])
        if s.sum() < 50:
            continue
        th, rr = theta[s], r[s]
        amps = {}
        for n in orders:
            e = np.exp(-1j * n * th)
            amps[str(n)] = [
                float(2 * abs(np.mean(rr[:, 0] * e))),
                float(2 * abs(np.mean(rr[:, 1] * e))),
            ]
        rows.append(
            {
                "speed_lo_rad_s": float(edges[j]),
                "speed_hi_rad_s": float(edges[j + 1]),
                "orders": amps,
            }
        )
    return rows


def residual_maps(probe: Probe, r_base: np.ndarray, r_aug: np.ndarray) -> dict:
    rec, k = probe.rec, probe.idx
    th = rec.theta_e_rad[k]
    om = rec.omega_e_rad_s[k]
    i_dq = rot(abc_to_ab(rec.i_abc[k]), -th)
    mag = np.hypot(i_dq[:, 0], i_dq[:, 1])
    ang = np.arctan2(i_dq[:, 1], i_dq[:, 0])
    ia, ib = rec.i_abc[k, 0], rec.i_abc[k, 1]
    sector = (ia > 0).astype(int) * 4 + (ib > 0).astype(int) * 2 + ((-ia - ib) > 0).astype(int)
    t = rec.t_s[k]
    sp = np.abs(om)
    out = {}
    for name, r in (("base", r_base), ("augmented", r_aug)):
        out[name] = {
            "speed": _binned(sp, r, np.quantile(sp, np.linspace(0, 1, 6))),
            "current": _binned(mag, r, np.quantile(mag, np.linspace(0, 1, 6))),
            "current_angle": _binned(ang, r, np.linspace(-np.pi, np.pi, 9)),
            "electrical_angle": _binned(th, r, np.linspace(0, 2 * np.pi, 13)),
            "current_sign_sector": _binned(sector.astype(float), r, np.arange(-0.5, 8.0, 1.0)),
            "time": _binned(t, r, np.linspace(t.min(), t.max() + 1e-12, 11)),
            "order_spectrum": order_spectrum(th, r, sp),
        }
    return out
