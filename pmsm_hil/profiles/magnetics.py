"""What the sensorless estimator needs from a motor's flux map (docs/sensorless.md).

The ripple PLL predicts the current change over one period from the voltage across the
inductances, di = Ts Gamma(i) U, with Gamma the inverse of the incremental inductance matrix
d(psi)/d(i). The firmware holds Gamma at the nodes of the map (within the current range the drive
uses) and interpolates bilinearly. The node derivatives are the map's own finite differences
(central inside, one-sided at the edges): the same node slopes as the emulator's bicubic Hermite
patches (firmware/sim/plant_map.c), so at the nodes the two agree exactly.

The polarity signature is the relative asymmetry of Gamma_dd at +-i_pulse on the d axis,
(g+ - g-)/(g+ + g-): the start-up test measures the same quantity and compares signs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fluxmap import FluxMap

# The firmware's table (firmware/core/ripple_err.h RERR_TAB_MAX)
TABLE_MAX_NODES = 400
# Physics default when a motor has no flux map: the magnet's flux adds to positive i_d, so the
# iron saturates on that side first and Gamma_dd is larger there. Only the sign is used; its size
# is a typical one for an IPMSM at half its rated current.
ASYM_PHYSICS_DEFAULT = 0.05


@dataclass
class GammaTable:
    """Gamma at the nodes of a regular grid; g[k, j, :] = (g_dd, g_qq, g_dq, g_qd) in 1/H."""

    i_d_a: np.ndarray
    i_q_a: np.ndarray
    g: np.ndarray  # (nq, nd, 4)

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.i_d_a), len(self.i_q_a)


def gamma_nodes(fm: FluxMap) -> np.ndarray:
    """(nq, nd, 4): the inverse incremental inductance matrix at every node of the map."""
    l_dd = np.gradient(fm.psi_d_wb, fm.i_d_a, axis=1)
    l_dq = np.gradient(fm.psi_d_wb, fm.i_q_a, axis=0)
    l_qd = np.gradient(fm.psi_q_wb, fm.i_d_a, axis=1)
    l_qq = np.gradient(fm.psi_q_wb, fm.i_q_a, axis=0)
    det = l_dd * l_qq - l_dq * l_qd
    if np.any(det <= 0):
        raise ValueError("flux map: an incremental inductance matrix is not positive definite")
    return np.stack([l_qq / det, l_dd / det, -l_dq / det, -l_qd / det], axis=-1)


def gamma_table(fm: FluxMap, i_d_min_a: float, i_max_a: float, ripple_a: float = 4.0) -> GammaTable:
    """The nodes the drive can reach, one node beyond: i_d from i_d_min_a - ripple_a (the most
    negative reference, MTPA at the current limit) to +ripple_a, i_q within +-(i_max_a +
    ripple_a); thinned by taking every n-th node until the table fits the firmware's."""
    g = gamma_nodes(fm)
    jd = np.flatnonzero((fm.i_d_a >= i_d_min_a - ripple_a) & (fm.i_d_a <= ripple_a))
    kq = np.flatnonzero(np.abs(fm.i_q_a) <= i_max_a + ripple_a)
    if len(jd) < 2:
        jd = np.arange(len(fm.i_d_a))
    if len(kq) < 2:
        kq = np.arange(len(fm.i_q_a))
    jd = np.arange(max(jd[0] - 1, 0), min(jd[-1] + 2, len(fm.i_d_a)))
    kq = np.arange(max(kq[0] - 1, 0), min(kq[-1] + 2, len(fm.i_q_a)))
    step = 1
    while len(jd[::step]) * len(kq[::step]) > TABLE_MAX_NODES:
        step += 1
    jd, kq = jd[::step], kq[::step]
    return GammaTable(fm.i_d_a[jd], fm.i_q_a[kq], g[np.ix_(kq, jd)])


def gamma_at(t: GammaTable, i_d_a: float, i_q_a: float) -> np.ndarray:
    """Bilinear interpolation, clamped to the edges (as the firmware's rerr_gamma_at)."""
    x = np.clip((i_d_a - t.i_d_a[0]) / (t.i_d_a[1] - t.i_d_a[0]), 0.0, len(t.i_d_a) - 1 - 1e-9)
    y = np.clip((i_q_a - t.i_q_a[0]) / (t.i_q_a[1] - t.i_q_a[0]), 0.0, len(t.i_q_a) - 1 - 1e-9)
    j, k = int(x), int(y)
    fx, fy = x - j, y - k
    lo = t.g[k, j] + fx * (t.g[k, j + 1] - t.g[k, j])
    hi = t.g[k + 1, j] + fx * (t.g[k + 1, j + 1] - t.g[k + 1, j])
    return lo + fy * (hi - lo)


def polarity_signature(fm: FluxMap | None, i_pulse_a: float) -> float:
    """(g+ - g-)/(g+ + g-) of Gamma_dd at i_d = +-i_pulse_a, i_q = 0; the physics default's sign
    when there is no map."""
    if fm is None:
        return ASYM_PHYSICS_DEFAULT
    t = GammaTable(fm.i_d_a, fm.i_q_a, gamma_nodes(fm))
    g_pos = float(gamma_at(t, i_pulse_a, 0.0)[0])
    g_neg = float(gamma_at(t, -i_pulse_a, 0.0)[0])
    return (g_pos - g_neg) / (g_pos + g_neg)
