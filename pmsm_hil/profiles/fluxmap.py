"""Flux maps for the saturation effect: psi_d(i_d, i_q), psi_q(i_d, i_q) on a regular current grid.

CSV format (profiles/maps/*.csv): lines starting with ``#`` are comments (source, derivation); a
header row ``i_d_a,i_q_a,psi_d_wb,psi_q_wb``; one row per grid node, in any order. The nodes must
lie on a regular grid (constant spacing per axis, at most 64 nodes per axis); nodes may be missing
(a measured map usually covers only the current circle): they are filled by linear extrapolation
from their neighbours, repeated outwards until the rectangle is full (``fill_missing``). The plant
interpolates the rectangle by bicubic Hermite patches (firmware/sim/plant.c, plant_map_build) and
extends it linearly beyond its edges.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass

import numpy as np

MAX_NODES = 64
COLUMNS = ("i_d_a", "i_q_a", "psi_d_wb", "psi_q_wb")


class FluxMapError(ValueError):
    pass


@dataclass
class FluxMap:
    """A filled rectangular flux map; arrays indexed [k (i_q), j (i_d)]."""

    i_d_a: np.ndarray  # node currents along i_d (nd,)
    i_q_a: np.ndarray  # node currents along i_q (nq,)
    psi_d_wb: np.ndarray  # (nq, nd)
    psi_q_wb: np.ndarray  # (nq, nd)
    measured: np.ndarray  # (nq, nd) bool: node given in the file
    path: str = ""
    sha256: str = ""

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.i_d_a), len(self.i_q_a)

    def settings(self) -> dict:
        """The sim board's keys for this map (emu_set / emu_set_array)."""
        nd, nq = self.shape
        return {
            "sat_nd": nd,
            "sat_nq": nq,
            "sat_id0_a": float(self.i_d_a[0]),
            "sat_did_a": float(self.i_d_a[1] - self.i_d_a[0]),
            "sat_iq0_a": float(self.i_q_a[0]),
            "sat_diq_a": float(self.i_q_a[1] - self.i_q_a[0]),
            "sat_psi_d_wb": [float(x) for x in self.psi_d_wb.ravel()],
            "sat_psi_q_wb": [float(x) for x in self.psi_q_wb.ravel()],
        }

    def node(self, i_d: float, i_q: float) -> tuple[float, float]:
        j = int(np.argmin(np.abs(self.i_d_a - i_d)))
        k = int(np.argmin(np.abs(self.i_q_a - i_q)))
        return float(self.psi_d_wb[k, j]), float(self.psi_q_wb[k, j])

    def small_current(self) -> tuple[float, float, float]:
        """(psi_f_wb, l_d_h, l_q_h) at small current: psi_d at the origin and the slopes of psi_d
        along i_d and of psi_q along i_q there (least squares over the grid nodes within two steps
        of the origin, on the node lines nearest to it)."""
        k0 = int(np.argmin(np.abs(self.i_q_a)))
        j0 = int(np.argmin(np.abs(self.i_d_a)))
        near_d = np.abs(self.i_d_a - self.i_d_a[j0]) <= 2.01 * abs(self.i_d_a[1] - self.i_d_a[0])
        near_q = np.abs(self.i_q_a - self.i_q_a[k0]) <= 2.01 * abs(self.i_q_a[1] - self.i_q_a[0])
        l_d, psi_f = np.polyfit(self.i_d_a[near_d], self.psi_d_wb[k0, near_d], 1)
        l_q = np.polyfit(self.i_q_a[near_q], self.psi_q_wb[near_q, j0], 1)[0]
        return float(psi_f), float(l_d), float(l_q)

    def scaled_to(self, psi_f_wb: float, l_d_h: float, l_q_h: float) -> tuple[FluxMap, dict]:
        """This map's saturation carried over to a motor with other small-current values, by
        scaling its co-energy: W'(i_d, i_q) = c W'_map(s_d i_d, s_q i_q), so psi_d = c s_d
        psi_d,map(s_d i_d, s_q i_q) and psi_q = c s_q psi_q,map(...), which keeps the map
        reciprocal (torque and voltage equations energy-consistent) and gives the motor's psi_f,
        L_d and L_q at small current: s_d = (L_d / L_d,map)(psi_f,map / psi_f), c = psi_f /
        (s_d psi_f,map), s_q = sqrt(L_q / (c L_q,map)). The nodes move to i_map / s (each axis
        saturates at its own scaled current); nothing is interpolated. Returns the map and the
        factors (docs/rigs.md, saturation)."""
        psi_m, l_d_m, l_q_m = self.small_current()
        if min(psi_f_wb, l_d_h, l_q_h, psi_m, l_d_m, l_q_m) <= 0.0:
            raise FluxMapError(
                f"cannot scale the map (psi_f {psi_m:.4g} Wb, L_d {l_d_m:.4g} H, L_q {l_q_m:.4g} H)"
                f" to psi_f {psi_f_wb:.4g} Wb, L_d {l_d_h:.4g} H, L_q {l_q_h:.4g} H: all must be > 0"
            )
        s_d = (l_d_h / l_d_m) * (psi_m / psi_f_wb)
        c = psi_f_wb / (s_d * psi_m)
        s_q = float(np.sqrt(l_q_h / (c * l_q_m)))
        fm = FluxMap(
            self.i_d_a / s_d,
            self.i_q_a / s_q,
            c * s_d * self.psi_d_wb,
            c * s_q * self.psi_q_wb,
            self.measured.copy(),
            self.path,
            self.sha256,
        )
        info = {"s_d": s_d, "s_q": s_q, "c": c, "psi_f_wb": psi_m, "l_d_h": l_d_m, "l_q_h": l_q_m}
        return fm, info

    def metadata(self) -> dict[str, str]:
        nd, nq = self.shape
        return {
            "map_file": os.path.basename(self.path),
            "map_sha256": self.sha256,
            "map_grid": f"{nd}x{nq} i_d {self.i_d_a[0]:g}..{self.i_d_a[-1]:g} A, "
            f"i_q {self.i_q_a[0]:g}..{self.i_q_a[-1]:g} A",
            "map_nodes_measured": str(int(self.measured.sum())),
            "map_psi_d_0_0_wb": repr(float(self.node(0.0, 0.0)[0])),
        }


# A rig's map is taken as the motor's own when its small-current values are within these of the
# motor file's (the least-squares slopes near the origin read a few % off a map's nominal values);
# otherwise its saturation is carried over to the motor by FluxMap.scaled_to.
OWN_PSI_F_REL = 0.05
OWN_L_REL = 0.15


def for_motor(fm: FluxMap, psi_f_wb: float, l_d_h: float, l_q_h: float) -> tuple[FluxMap, dict]:
    """The rig's map as the plant of this motor uses it: as it is when it is the motor's own
    (within OWN_PSI_F_REL, OWN_L_REL), else scaled to the motor's small-current values. The dict
    says which (empty: as it is)."""
    psi_m, l_d_m, l_q_m = fm.small_current()
    own = (
        abs(psi_m / psi_f_wb - 1.0) <= OWN_PSI_F_REL
        and abs(l_d_m / l_d_h - 1.0) <= OWN_L_REL
        and abs(l_q_m / l_q_h - 1.0) <= OWN_L_REL
    )
    if own:
        return fm, {}
    return fm.scaled_to(psi_f_wb, l_d_h, l_q_h)


def _axis(values: np.ndarray, name: str) -> np.ndarray:
    u = np.unique(values)
    if len(u) < 2:
        raise FluxMapError(f"{name}: needs at least 2 distinct grid values")
    if len(u) > MAX_NODES:
        raise FluxMapError(f"{name}: {len(u)} grid values, at most {MAX_NODES}")
    steps = np.diff(u)
    h = steps.min()
    k = np.rint((u - u[0]) / h)
    if np.max(np.abs(u - (u[0] + k * h))) > 1e-6 * max(1.0, h):
        raise FluxMapError(f"{name}: values are not on a regular grid (step {h:g})")
    n = int(k[-1]) + 1
    if n > MAX_NODES:
        raise FluxMapError(f"{name}: the regular grid has {n} nodes, at most {MAX_NODES}")
    return u[0] + h * np.arange(n)


def fill_missing(f: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Fill the unknown nodes of a 2-D grid by linear extrapolation from known neighbours along the
    grid lines (2 f[x-1] - f[x-2], averaged over the directions available), repeated outwards."""
    f = f.copy()
    known = known.copy()
    nq, nd = f.shape
    while not known.all():
        new_vals = {}
        for k in range(nq):
            for j in range(nd):
                if known[k, j]:
                    continue
                est = []
                for dk, dj in ((0, 1), (0, -1), (1, 0), (-1, 0)):
                    k1, j1, k2, j2 = k + dk, j + dj, k + 2 * dk, j + 2 * dj
                    if 0 <= k2 < nq and 0 <= j2 < nd and known[k1, j1] and known[k2, j2]:
                        est.append(2.0 * f[k1, j1] - f[k2, j2])
                if not est:
                    for dk, dj in ((0, 1), (0, -1), (1, 0), (-1, 0)):
                        k1, j1 = k + dk, j + dj
                        if 0 <= k1 < nq and 0 <= j1 < nd and known[k1, j1]:
                            est.append(f[k1, j1])
                if est:
                    new_vals[(k, j)] = float(np.mean(est))
        if not new_vals:
            raise FluxMapError("flux map has no measured node to extrapolate from")
        for (k, j), v in new_vals.items():
            f[k, j] = v
            known[k, j] = True
    return f


def read_csv(path: str) -> np.ndarray:
    """Rows of (i_d_a, i_q_a, psi_d_wb, psi_q_wb) from a flux-map CSV. An error names the file's
    line (comment and blank lines counted), the column and the value as the file writes it."""
    with open(path, encoding="utf-8") as fh:
        lines = [
            (n, ln.strip())
            for n, ln in enumerate(fh, start=1)
            if ln.strip() and not ln.lstrip().startswith("#")
        ]
    if not lines:
        raise FluxMapError("empty file")
    hline, head_text = lines[0]
    head = [h.strip() for h in head_text.split(",")]
    missing = [c for c in COLUMNS if c not in head]
    if missing:
        raise FluxMapError(
            f"line {hline}: missing column(s) {', '.join(missing)} (need {', '.join(COLUMNS)})"
        )
    idx = [head.index(c) for c in COLUMNS]
    rows = []
    first: dict[tuple[float, float], int] = {}
    for n, ln in lines[1:]:
        parts = ln.split(",")
        if len(parts) != len(head):
            raise FluxMapError(f"line {n}: {len(parts)} values for {len(head)} columns: {ln!r}")
        row = []
        for c, i in zip(COLUMNS, idx, strict=True):
            v = parts[i].strip()
            try:
                x = float(v)
            except ValueError:
                raise FluxMapError(f"line {n}: {c} = {v!r} is not a number") from None
            if not math.isfinite(x):
                raise FluxMapError(f"line {n}: {c} = {v!r} is not finite")
            row.append(x)
        node = (row[0], row[1])
        if node in first:
            raise FluxMapError(
                f"line {n}: the node i_d_a = {parts[idx[0]].strip()}, i_q_a = "
                f"{parts[idx[1]].strip()} is given twice (first on line {first[node]})"
            )
        first[node] = n
        rows.append(row)
    if len(rows) < 4:
        raise FluxMapError(f"only {len(rows)} data row(s); at least 4 are needed")
    return np.array(rows, dtype=float)


def from_points(data: np.ndarray, path: str = "", sha256: str = "") -> FluxMap:
    i_d = _axis(data[:, 0], "i_d_a")
    i_q = _axis(data[:, 1], "i_q_a")
    nd, nq = len(i_d), len(i_q)
    pd = np.zeros((nq, nd))
    pq = np.zeros((nq, nd))
    known = np.zeros((nq, nd), dtype=bool)
    j = np.rint((data[:, 0] - i_d[0]) / (i_d[1] - i_d[0])).astype(int)
    k = np.rint((data[:, 1] - i_q[0]) / (i_q[1] - i_q[0])).astype(int)
    if known[k, j].any() or len(set(zip(k.tolist(), j.tolist(), strict=False))) != len(data):
        raise FluxMapError("a grid node is given twice")
    pd[k, j] = data[:, 2]
    pq[k, j] = data[:, 3]
    known[k, j] = True
    pd, pq = fill_missing(pd, known), fill_missing(pq, known)
    _check_rising(pd, i_d, i_q, "psi_d_wb", "i_d_a", 1)
    _check_rising(pq, i_d, i_q, "psi_q_wb", "i_q_a", 0)
    return FluxMap(i_d, i_q, pd, pq, known, path, sha256)


def _check_rising(
    psi: np.ndarray, i_d: np.ndarray, i_q: np.ndarray, name: str, along: str, ax: int
):
    """Each flux must rise with its own current everywhere (a positive incremental inductance):
    the plant finds the currents from the flux linkage by Newton steps, which a map that falls
    or stays flat cannot give (docs/plant.md). Raises FluxMapError naming the first such cell."""
    step = np.diff(psi, axis=ax)
    bad = np.argwhere(~(step > 0))
    if not len(bad):
        return
    k, j = (int(x) for x in bad[0])
    if ax == 1:  # along i_d at i_q[k]: nodes j, j + 1
        where = f"between i_d_a = {i_d[j]:g} and {i_d[j + 1]:g} A at i_q_a = {i_q[k]:g} A"
        a, b = psi[k, j], psi[k, j + 1]
    else:  # along i_q at i_d[j]: nodes k, k + 1
        where = f"between i_q_a = {i_q[k]:g} and {i_q[k + 1]:g} A at i_d_a = {i_d[j]:g} A"
        a, b = psi[k, j], psi[k + 1, j]
    raise FluxMapError(
        f"{name} does not rise with {along} {where} ({a:.6g} -> {b:.6g} Wb; {len(bad)} such "
        "cells): a flux map needs a positive incremental inductance everywhere (the plant finds "
        "the currents from the flux)"
    )


def load_flux_map(path: str) -> FluxMap:
    """Read, check and fill a flux-map CSV (raises OSError or FluxMapError)."""
    with open(path, "rb") as fh:
        sha = hashlib.sha256(fh.read()).hexdigest()
    return from_points(read_csv(path), path, sha)
