"""How closely smooth saturation families fit a flux map's incremental inductances: the gap
diagnosis's arctangent family (pmsm_hil/gap/model.py, six parameters) and independent polynomials
of psi_d (even in i_q) and psi_q (odd in i_q) of rising degree, against the map's own Jacobian
(central differences on its grid). The one-step residual sees the incremental inductances, so
what no family fits stays in the residual after `saturation` (docs/gap.md, "The dead time on the
SEW rig"). Also printed: how far the map's Jacobian is from a co-energy's (dpsi_d/di_q against
dpsi_q/di_d) and how far the map is from the symmetry in i_q that every family here assumes.

    python3 benchmarks/sat_family.py [--map profiles/maps/sew-cm3c80s.csv]
                                     [--motor profiles/motors/sew-cm3c80s.yaml]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import least_squares

from pmsm_hil.gap.effects import EFFECTS
from pmsm_hil.gap.model import MotorModel, PlantTerms, _flux
from pmsm_hil.profiles import load_motor
from pmsm_hil.profiles.fluxmap import read_csv


def jacobian(data: np.ndarray):
    """Grid points with a neighbour on each side along both axes, and (dpsi_d/di_d, dpsi_d/di_q,
    dpsi_q/di_d, dpsi_q/di_q) there by central differences, H."""
    g = {(a, b): np.array((c, e)) for a, b, c, e in data}
    ud, uq = np.unique(data[:, 0]), np.unique(data[:, 1])
    pts, jac = [], []
    for a, b in g:
        j, k = np.searchsorted(ud, a), np.searchsorted(uq, b)
        if not (0 < j < len(ud) - 1 and 0 < k < len(uq) - 1):
            continue
        n = [(ud[j + 1], b), (ud[j - 1], b), (a, uq[k + 1]), (a, uq[k - 1])]
        if all(p in g for p in n):
            by_d = (g[n[0]] - g[n[1]]) / (ud[j + 1] - ud[j - 1])
            by_q = (g[n[2]] - g[n[3]]) / (uq[k + 1] - uq[k - 1])
            pts.append((a, b))
            jac.append((by_d[0], by_q[0], by_d[1], by_q[1]))
    return np.array(pts, float), np.array(jac)


def arctan_fit(m: MotorModel, pts: np.ndarray, jac: np.ndarray) -> np.ndarray:
    """Residuals (H) of the arctangent family's best fit to the Jacobian's four entries (its
    matrix is symmetric: one cross term against both of the map's)."""
    target = np.r_[jac[:, 0], jac[:, 1], jac[:, 2], jac[:, 3]]
    e = EFFECTS["saturation"]

    def res(x):
        _, mat = _flux(m, pts, PlantTerms(sat=tuple(x)), m.psi_f_wb)
        ldd, ldq, lqq = (np.broadcast_to(v, len(pts)) for v in mat)
        return np.r_[ldd, ldq, ldq, lqq] - target

    best = None
    for x0 in (e.x0, *e.starts):
        r = least_squares(res, x0, bounds=(e.lower, e.upper))
        best = r if best is None or r.cost < best.cost else best
    assert best is not None
    return best.fun


def poly_fit(pts: np.ndarray, jac: np.ndarray, deg: int, i_ref: float) -> tuple[int, np.ndarray]:
    """Number of parameters and residuals (H) of polynomials of total degree deg, psi_d even and
    psi_q odd in i_q, fitted to all four Jacobian entries."""
    a, b = pts[:, 0] / i_ref, pts[:, 1] / i_ref
    out, n = [], 0
    for odd, (col_d, col_q) in ((False, (0, 1)), (True, (2, 3))):
        d_a, d_b = [], []
        for j in range(deg + 1):
            for k in range(deg + 1 - j):
                if (k % 2 == 1) != odd or j + k == 0:
                    continue
                d_a.append(j * a ** max(j - 1, 0) * b**k / i_ref)
                d_b.append(k * a**j * b ** max(k - 1, 0) / i_ref)
        basis = np.r_[np.array(d_a).T, np.array(d_b).T]
        target = np.r_[jac[:, col_d], jac[:, col_q]]
        coef = np.linalg.lstsq(basis, target, rcond=None)[0]
        out.append(basis @ coef - target)
        n += len(coef)
    return n, np.concatenate(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--map", default="profiles/maps/sew-cm3c80s.csv")
    ap.add_argument("--motor", default="profiles/motors/sew-cm3c80s.yaml")
    args = ap.parse_args()
    data = read_csv(args.map)
    m = MotorModel.from_motor(load_motor(args.motor))
    pts, jac = jacobian(data)
    mh = lambda r: 1e3 * float(np.sqrt(np.mean(np.square(r))))  # noqa: E731
    print(f"{args.map}: {len(data)} points, {len(pts)} with all four neighbours")
    print(
        f"incremental inductances: dpsi_d/di_d {1e3 * jac[:, 0].min():.2f}..{1e3 * jac[:, 0].max():.2f}"
        f" mH, dpsi_q/di_q {1e3 * jac[:, 3].min():.2f}..{1e3 * jac[:, 3].max():.2f} mH,"
        f" the cross terms' difference (a co-energy has none) {mh(jac[:, 1] - jac[:, 2]):.3f} mH rms"
    )
    g = {(a, b): (c, e) for a, b, c, e in data}
    pairs = [(g[(a, b)], g[(a, -b)]) for a, b in g if b > 0 and (a, -b) in g]
    print(
        "symmetry in i_q: psi_d(i_d, i_q) - psi_d(i_d, -i_q) "
        f"{mh([p[0] - q[0] for p, q in pairs]):.2f} mWb rms, psi_q(i_d, i_q) + psi_q(i_d, -i_q) "
        f"{mh([p[1] + q[1] for p, q in pairs]):.2f} mWb rms"
    )
    nominal = np.r_[jac[:, 0] - m.l_d_h, jac[:, 1], jac[:, 2], jac[:, 3] - m.l_q_h]
    print(f"the motor file's constant L_d, L_q: {mh(nominal):.3f} mH rms off the Jacobian")
    print(f"arctangent family (6 parameters): {mh(arctan_fit(m, pts, jac)):.3f} mH rms")
    i_ref = float(np.max(np.abs(data[:, :2])))
    for deg in (3, 4, 5, 6):
        n, r = poly_fit(pts, jac, deg, i_ref)
        print(f"polynomials of degree {deg} ({n} parameters): {mh(r):.3f} mH rms")


if __name__ == "__main__":
    main()
