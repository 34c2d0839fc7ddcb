"""Derive the shipped flux maps (profiles/maps/) from the measured SEW CM3C80S map.

    python3 tools/derive_flux_map.py SEW_MAP.csv

writes
  profiles/maps/sew-cm3c80s.csv   the measured map as it is (comment header with its source)
  profiles/maps/paper-a-ipmsm.csv the map scaled to paper A's IPMSM (derivation in docs/rigs.md)

Paper A map, step by step (docs/rigs.md, "saturation"):
 1. fill the measured map's rectangle (nodes outside the current circle) by linear extrapolation
    (pmsm_hil.profiles.fluxmap.fill_missing), as the plant does when it loads the measured map;
 2. symmetrise in i_q: psi_d even, psi_q odd (removes the measurement's psi_q(0, 0) = -6 mWb offset);
 3. small-current parameters of the symmetrised map: psi_f_S = psi_d(0, 0), L_d,S and L_q,S as the
    least-squares slopes over -3 A <= i_d <= 1 A (at i_q = 0) and |i_q| <= 3 A (at i_d = 0);
 4. scale the co-energy, which keeps the map reciprocal (d psi_d / d i_q = d psi_q / d i_d):
    W'_A(i) = c W'_S(s i) + L_sig,q i_q^2 / 2, i.e. psi_A(i) = c s psi_S(s i) + (0, L_sig,q i_q), with
    s = L_d,A psi_f,S / (psi_f,A L_d,S)   (current scale: the d axis saturates as measured),
    c = psi_f,A / (s psi_f,S)            (psi_d,A(0, 0) = psi_f,A),
    L_sig,q = L_q,A - c s^2 L_q,S        (an unsaturable q-axis part makes up paper A's saliency);
    the nodes move to i / s.
"""

from __future__ import annotations

import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from pmsm_hil.profiles.fluxmap import load_flux_map  # noqa: E402

PSI_F_A, L_D_A, L_Q_A = 0.18, 5e-3, 12e-3  # paper A (profiles/motors/paper-a-ipmsm.yaml)
SOURCE = (
    "Measured flux-linkage map of an SEW CM3C80S servo PMSM (p = 4, current limit 16 A) on the "
    "Paderborn University (LEA) test bench; from upb-lea/gym-electric-motor, branch "
    "nonlinearities, examples/environment_features/saturated_pmsm/Reforce_PMSM_LUT.mat "
    "(MIT licence), converted to CSV with the grid in amperes."
)


def derive(sew_path: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    fm = load_flux_map(sew_path)
    i_d, i_q = fm.i_d_a, fm.i_q_a
    if not np.allclose(i_q, -i_q[::-1]):
        raise SystemExit("the i_q grid must be symmetric")
    pd = 0.5 * (fm.psi_d_wb + fm.psi_d_wb[::-1, :])
    pq = 0.5 * (fm.psi_q_wb - fm.psi_q_wb[::-1, :])
    k0, j0 = int(np.argmin(np.abs(i_q))), int(np.argmin(np.abs(i_d)))
    psi_f_s = pd[k0, j0]
    sel_d = (i_d >= -3) & (i_d <= 1)
    sel_q = np.abs(i_q) <= 3
    l_d_s = np.polyfit(i_d[sel_d], pd[k0, sel_d], 1)[0]
    l_q_s = np.polyfit(i_q[sel_q], pq[sel_q, j0], 1)[0]
    s = L_D_A * psi_f_s / (PSI_F_A * l_d_s)
    c = PSI_F_A / (s * psi_f_s)
    l_sig_q = L_Q_A - c * s * s * l_q_s
    id_a, iq_a = i_d / s, i_q / s
    pd_a = c * s * pd
    pq_a = c * s * pq + l_sig_q * iq_a[:, None]
    info = dict(psi_f_s=psi_f_s, l_d_s=l_d_s, l_q_s=l_q_s, s=s, c=c, l_sig_q=l_sig_q)
    return id_a, iq_a, pd_a, pq_a, info


def write_csv(path, header_lines, i_d, i_q, pd, pq, measured=None):
    with open(path, "w", encoding="utf-8") as f:
        for ln in header_lines:
            f.write(f"# {ln}\n")
        f.write("i_d_a,i_q_a,psi_d_wb,psi_q_wb\n")
        for k in range(len(i_q)):
            for j in range(len(i_d)):
                if measured is not None and not measured[k, j]:
                    continue
                f.write(f"{i_d[j]:.9g},{i_q[k]:.9g},{pd[k, j]:.9g},{pq[k, j]:.9g}\n")


def main() -> None:
    sew = sys.argv[1] if len(sys.argv) > 1 else "sew_cm3c80s_flux_map.csv"
    out = os.path.join(ROOT, "profiles", "maps")
    os.makedirs(out, exist_ok=True)
    with open(sew, encoding="utf-8") as f:
        raw = f.read()
    with open(os.path.join(out, "sew-cm3c80s.csv"), "w", encoding="utf-8") as f:
        f.write("# SEW CM3C80S flux map, measured, as it is (452 nodes inside the 16 A circle).\n")
        f.write(f"# Source: {SOURCE}\n")
        f.write(
            "# Note: psi_q(0, 0) = -6 mWb is a measurement artefact, kept. Format: docs/rigs.md.\n"
        )
        f.write(raw)
    id_a, iq_a, pd_a, pq_a, info = derive(sew)
    hdr = [
        "Paper A IPMSM flux map (psi_f 0.18 Wb, L_d 5 mH, L_q 12 mH at small current), derived from",
        "the measured SEW CM3C80S map by tools/derive_flux_map.py (method: docs/rigs.md).",
        f"Source of the measured map: {SOURCE}",
        f"Symmetrised SEW map: psi_f {info['psi_f_s']:.6g} Wb, L_d {info['l_d_s'] * 1e3:.4g} mH, "
        f"L_q {info['l_q_s'] * 1e3:.4g} mH (slopes at small current).",
        f"Co-energy scaling: current scale s = {info['s']:.6g} (node i = i_SEW / s), flux scale "
        f"c = {info['c']:.6g}, unsaturable q-axis part {info['l_sig_q'] * 1e3:.4g} mH.",
    ]
    write_csv(os.path.join(out, "paper-a-ipmsm.csv"), hdr, id_a, iq_a, pd_a, pq_a)
    for k, v in info.items():
        print(f"{k} = {v:.6g}")


if __name__ == "__main__":
    main()
