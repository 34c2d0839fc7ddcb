"""The settled-plateau view (docs/gap.md, "Which"): the one-step residual's mean over each settled
speed plateau, after the selected effects, for the effects that shift the steady-state voltages by
a little and that the residual's mean square hardly weighs against the switching ripple:

- ``iron_loss``: the iron-loss current beside the magnetising one, a d-voltage even in speed and
  growing as its square;
- ``encoder``: the angle's zero off, the dq frame turned, a d-voltage odd in speed (the back-EMF
  seen on d);
- ``thermal``: the winding's resistance and the magnet's flux at another temperature, on q in
  proportion to the current and the speed.

A plateau is the second half of a stretch where the 20 ms mean speed stays within 0.5 % (at least
2 rad/s) and the load is constant, lasting at least 0.15 s. Every subset of the candidates is
fitted jointly to the plateau means in volts, the selected effects held at their fitted values
(one at a time they take up each other's part), on a model of the means linear in the candidates'
parameters about their null values; the subset whose fits on random halves of the plateaus best
predict the other halves is taken (the smallest within ``TIE_REL`` of the best) when it lowers
their sum of squares by at least ``MIN_GAIN_REL`` and by ``MIN_GAIN_V2`` per plateau, and, fitted
again in full (nonlinear), has every value inside its range.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from scipy.optimize import least_squares, lsq_linear

from pmsm_hil.gap.effects import EFFECTS, Effect, primary_value
from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.probe import Probe
from pmsm_hil.gap.record import ControlRecord

__all__ = ["find_plateaus", "less_iron_drag", "plateau_bootstrap", "plateau_view"]

CANDIDATES = ("iron_loss", "encoder", "thermal")
SMOOTH_S = 0.02
STEADY_REL, STEADY_MIN_RAD_S = 0.005, 2.0
MIN_PLATEAU_S = 0.15
MIN_PLATEAUS = 6
MIN_GAIN_REL = 0.25  # of the held-out plateaus' sum of squares
MIN_GAIN_V2 = 0.05  # per plateau: (0.22 V)^2
SPLITS = 3  # random halvings of the plateaus for the held-out gain
# the candidates' null values and the steps of the central differences about them
NULL = {"iron_loss": (0.0,), "encoder": (0.0,), "thermal": (0.0, 0.0)}
STEP = {"iron_loss": (2.0,), "encoder": (0.01,), "thermal": (20.0, 20.0)}
TIE_REL = 0.1  # a smaller subset within 10 % of the best held-out gain is taken instead
BOOT = 1000  # resamples of the plateaus for the intervals


def find_plateaus(rec: ControlRecord, omega: np.ndarray) -> list[tuple[int, int]]:
    """[a, b) sample ranges: the settled second half of each steady stretch (see the module)."""
    n20 = max(round(SMOOTH_S / rec.ts_s), 1)
    w = np.convolve(omega, np.ones(n20) / n20, mode="same")
    load = rec.load_nm if rec.load_nm is not None else np.zeros(rec.n)
    out = []
    for ra, rb in rec.runs:
        i = ra + n20
        end = rb - n20
        while i < end:
            tol = max(STEADY_REL * abs(w[i]), STEADY_MIN_RAD_S)
            j = i
            while j + 1 < end and abs(w[j + 1] - w[i]) <= tol and load[j + 1] == load[i]:
                j += 1
            if (j - i) * rec.ts_s >= MIN_PLATEAU_S:
                out.append(((i + j) // 2, j))
            i = j + 1
    return out


def _rows(probe: Probe, plateaus: Sequence[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """The residual rows (indices into probe.idx) inside the plateaus, and each row's plateau."""
    k = probe.idx
    sel, lab = [], []
    for p, (a, b) in enumerate(plateaus):
        s = np.nonzero((k >= a) & (k < b))[0]
        sel.append(s)
        lab.append(np.full(len(s), p))
    return np.concatenate(sel), np.concatenate(lab)


class _PlateauFit:
    """The effects ``names`` fitted jointly to the plateau means with ``fixed`` held."""

    def __init__(self, probe: Probe, fixed, n: int, sel, lab, names: tuple[str, ...]):
        self.probe, self.fixed, self.names = probe, fixed, names
        self.sel, self.lab, self.n = sel, lab, n
        self.lo = np.array([v for c in names for v in EFFECTS[c].lower], float)
        self.hi = np.array([v for c in names for v in EFFECTS[c].upper], float)

    def effects(self, z: np.ndarray) -> list[tuple[Effect, np.ndarray]]:
        out, p = [], 0
        for c in self.names:
            k = len(EFFECTS[c].params)
            out.append((EFFECTS[c], z[p : p + k]))
            p += k
        return out

    def means(self, z: np.ndarray) -> np.ndarray:
        r = self.probe.residual([*self.fixed, *self.effects(z)], self.sel)
        cnt = np.bincount(self.lab, None, self.n)
        return np.stack([np.bincount(self.lab, r[:, d], self.n) / cnt for d in range(2)], 1)

    def fit(self, z0: np.ndarray):
        """Nonlinear least squares on every plateau from ``z0``."""
        return least_squares(
            lambda z: self.means(z).ravel(),
            np.clip(z0, self.lo, self.hi),
            bounds=(self.lo, self.hi),
            x_scale="jac",
        )


def _held_out(m0: np.ndarray, jac: np.ndarray, cols, lo, hi, halves) -> tuple[float, np.ndarray]:
    """The held-out sum of squares of the plateau means (linear model m0 + jac dz on the columns
    ``cols``, bounded): fitted on each half, judged on the other, averaged over the halvings; and
    dz fitted on every plateau."""
    a, b = jac[:, cols], -m0
    rows = lambda part: np.repeat(part, 2)  # noqa: E731  (the d and q mean of each plateau)
    cv = 0.0
    for h in halves:
        for part in (h, ~h):
            dz = lsq_linear(a[rows(part)], b[rows(part)], bounds=(lo, hi)).x
            cv += float(np.sum((a[rows(~part)] @ dz - b[rows(~part)]) ** 2)) / len(halves)
    return cv, lsq_linear(a, b, bounds=(lo, hi)).x


def plateau_bootstrap(
    jac: np.ndarray, resid: np.ndarray, z: np.ndarray, lo: np.ndarray, hi: np.ndarray, seed: int = 1
) -> np.ndarray:
    """The fit ``z`` again on ``BOOT`` resamples of the plateaus (drawn with replacement), each by
    one Gauss-Newton step from ``z`` on the final fit's Jacobian and residuals (rows plateau-major,
    d then q) and clipped to the range: (BOOT, len(z)). A plateau's misfit is a model error as much
    as noise (the loaded plateaus carry the saturation model's), so the spread between plateaus,
    not the residuals' scatter, bounds the fit."""
    n, k = len(resid) // 2, len(z)
    jb = jac.reshape(n, 2, k)
    rb = resid.reshape(n, 2)
    gram = np.einsum("pik,pil->pkl", jb, jb).reshape(n, k * k)
    grad = np.einsum("pik,pi->pk", jb, rb)
    counts = (
        np.random.default_rng(seed).multinomial(n, np.full(n, 1.0 / n), size=BOOT).astype(float)
    )
    a = (counts @ gram).reshape(BOOT, k, k)
    g = counts @ grad
    dz = -np.einsum("bkl,bl->bk", np.linalg.pinv(a), g)
    return np.clip(z + dz, lo, hi)


def plateau_view(
    probe: Probe, motor: MotorModel, fixed: list[tuple[Effect, np.ndarray]], exclude: Sequence[str]
) -> tuple[list[dict], dict]:
    """The candidates not in ``exclude`` taken on the settled plateaus (effect entries, selected
    or not), and a summary of the plateaus' means before and after."""
    rec = probe.rec
    plateaus = find_plateaus(rec, probe.omega)
    n = len(plateaus)
    summary: dict = {"plateaus": n}
    cands = tuple(c for c in CANDIDATES if c not in exclude)
    if n < MIN_PLATEAUS or not cands:
        summary["note"] = (  # the console prints it after "settled plateaus: "
            f"{n} found, the view needs {MIN_PLATEAUS}: not used"
            if n < MIN_PLATEAUS
            else f"{n} found; no candidate left for the view (the one-step residual took them)"
        )
        return [], summary
    sel, lab = _rows(probe, plateaus)
    # held-out plateaus: random halves (fixed seed), each half judged by a fit on the other (a
    # profile alternating, say, unloaded and loaded plateaus would make every-other-one folds of
    # one kind each)
    rng = np.random.default_rng(0)
    halves = [rng.permutation(n) % 2 == 0 for _ in range(SPLITS)]
    # the plateau means linear in the candidates' parameters about their null values (central
    # differences): every subset's held-out fits are then linear least squares; the subset taken
    # is fitted in full at the end
    every = _PlateauFit(probe, fixed, n, sel, lab, cands)
    z_null = np.array([v for c in cands for v in NULL[c]], float)
    step = np.array([v for c in cands for v in STEP[c]], float)
    m0 = every.means(z_null).ravel()
    jac = np.stack(
        [
            (every.means(z_null + dz).ravel() - every.means(z_null - dz).ravel()) / (2 * dz[j])
            for j, dz in enumerate(np.diag(step))
        ],
        1,
    )
    sse0 = float(np.sum(m0**2))
    summary["rms_before_v"] = [float(v) for v in np.sqrt(np.mean(m0.reshape(n, 2) ** 2, 0))]
    # every subset of the candidates, fitted jointly (one at a time they take up each other's part:
    # an encoder offset is odd in speed, iron loss even, the temperatures follow the currents)
    offs = np.cumsum([0, *[len(NULL[c]) for c in cands]])
    tried = []
    for k in range(1, len(cands) + 1):
        for names in itertools.combinations(cands, k):
            cols = np.concatenate(
                [np.arange(offs[cands.index(c)], offs[cands.index(c) + 1]) for c in names]
            )
            cv, dz = _held_out(
                m0, jac, cols, every.lo[cols] - z_null[cols], every.hi[cols] - z_null[cols], halves
            )
            tried.append((cv, names, z_null[cols] + dz))
    tried.sort(key=lambda t: (t[0], len(t[1])))
    cv = tried[0][0]
    # the smallest subset within TIE_REL of the best held-out fit
    cv, names, z_lin = min(
        (t for t in tried if t[0] <= cv + TIE_REL * max(sse0 - cv, 0.0)),
        key=lambda t: (len(t[1]), t[0]),
    )
    pf = _PlateauFit(probe, fixed, n, sel, lab, names)
    gain = sse0 - cv
    thr = max(MIN_GAIN_REL * sse0, MIN_GAIN_V2 * n)
    take = gain >= thr
    if take:  # the subset taken, fitted in full (the model, not its linear part)
        res = pf.fit(z_lin)
        z, after = res.x, pf.means(res.x)
        take = bool(np.all(z > pf.lo) & np.all(z < pf.hi))
        dof = max(after.size - len(z), 1)
        cov = np.linalg.pinv(res.jac.T @ res.jac) * float(np.sum(after**2)) / dof
        se_all = np.sqrt(np.maximum(np.diag(cov), 0.0))
        boot = plateau_bootstrap(res.jac, res.fun, z, pf.lo, pf.hi)
    else:  # below the threshold: the linear fit's values are quoted, nothing refitted
        z, se_all = z_lin, np.zeros(len(z_lin))
        after = m0.reshape(n, 2)
        boot = np.empty((0, len(z)))
    inside = bool(np.all(z > pf.lo) & np.all(z < pf.hi))
    entries: list[dict] = []
    p = 0
    for c in names:
        e = EFFECTS[c]
        x = z[p : p + len(e.params)]
        se = se_all[p : p + len(e.params)]
        ends = [primary_value(e, x + s * 1.96 * se, motor, rec.ts_s) for s in (-1, 1)]
        if len(boot):  # the wider of the fit's own interval and the plateaus' resampling's
            vals = [primary_value(e, zb[p : p + len(e.params)], motor, rec.ts_s) for zb in boot]
            ends += [float(v) for v in np.percentile(vals, [2.5, 97.5])]
        p += len(e.params)
        entries.append(
            {
                "name": c,
                "selected": take,
                "magnitude": primary_value(e, x, motor, rec.ts_s),
                "quantity": e.primary,
                "interval": [min(ends), max(ends)] if take else None,
                "parameters": e.report(x, motor),
                "closure": None,
                "evidence": f"settled plateaus ({n}), fitted with {' + '.join(names)}: the "
                f"held-out plateaus' mean residual down {gain:.3g} of {sse0:.3g} V^2 "
                f"(threshold {thr:.2g} V^2)"
                + ("" if inside else "; a fit at a bound of its range"),
            }
        )
    for c in cands:
        if c not in names:
            entries.append(
                {
                    "name": c,
                    "selected": False,
                    "magnitude": None,
                    "quantity": EFFECTS[c].primary,
                    "interval": None,
                    "closure": None,
                    "evidence": f"settled plateaus ({n}): not in the best held-out fit "
                    f"({' + '.join(names)})",
                }
            )
    summary["rms_after_v"] = [float(v) for v in np.sqrt(np.mean(after**2, 0))]
    summary["subsets"] = {" + ".join(t[1]): round(t[0], 3) for t in tried}
    summary["selected"] = [str(e["name"]) for e in entries if e["selected"]]
    return entries, summary


def less_iron_drag(effects: list[dict], motor: MotorModel) -> None:
    """When the plateaus found an iron loss and the torque balance a viscous friction: the balance
    had no iron loss in its model, so its viscous term took up the iron loss's drag, P_fe / w_m =
    1.5 p^2 psi_f^2 / R_fe per rad/s; that part leaves the friction (in place)."""
    by = {str(e["name"]): e for e in effects if e.get("selected")}
    iron, fric = by.get("iron_loss"), by.get("friction")
    if iron is None or fric is None:
        return
    par, ipar = fric.get("parameters"), iron.get("parameters")
    if not (isinstance(par, dict) and isinstance(ipar, dict) and "b_visc_nms" in par):
        return
    r_fe = float(ipar["r_fe_ohm"])
    if not r_fe > 0:
        return
    drag = 1.5 * motor.pole_pairs**2 * motor.psi_f_wb**2 / r_fe
    b = float(par["b_visc_nms"])
    par["b_visc_nms"] = max(b - drag, 0.0)
    fric["evidence"] = (
        f"{fric['evidence']}; viscous term {b:.3g} less the iron loss's drag {drag:.3g} N m s"
    )
