"""Fitting augmentations on training blocks; block-robust intervals (docs/gap.md, "How far")."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
from scipy.optimize import least_squares

from pmsm_hil.gap.effects import EFFECTS, PARAMETERS, Effect
from pmsm_hil.gap.probe import Probe

LIB = dict(EFFECTS, parameters=PARAMETERS)


class Closure(TypedDict):
    """What ``bootstrap_closure`` returns."""

    closure: float
    closure_interval: list[float]
    mse_gain: float
    mse_gain_se: float
    mse_gain_interval: list[float]


@dataclass
class Fit:
    names: tuple[str, ...]
    x: dict[str, np.ndarray]
    se: dict[str, np.ndarray]
    cost: float
    # per effect, its parameters' covariance (cluster-robust, as ``se``): the interval of a quantity
    # that combines two correlated parameters (the total delay) needs it
    cov: dict[str, np.ndarray] = field(default_factory=dict)

    def effects(self) -> list[tuple[Effect, np.ndarray]]:
        return [(LIB[n], self.x[n]) for n in self.names]


def _split(names, v):
    out, p = {}, 0
    for n in names:
        k = len(LIB[n].params)
        out[n] = v[p : p + k]
        p += k
    return out


_WORKER: dict[str, Probe] = {}  # the probe of a worker process of pmsm_hil.gap.pool


def set_worker_probe(probe: Probe) -> None:
    """The probe of this (worker) process: fits sent here, and ``Objective``s, evaluate on it."""
    _WORKER["probe"] = probe


def worker_probe() -> Probe:
    probe = _WORKER.get("probe")
    if probe is None:
        raise RuntimeError("a fit sent to a process that holds no probe (set_worker_probe)")
    return probe


class Objective:
    """The residual vector of the named effects at parameters z on the transitions idx[sel]. It
    pickles without its probe (a map-like ``workers`` sends it to processes that hold the probe:
    ``set_worker_probe``), so that the finite-difference columns of a fit's Jacobian can be
    evaluated side by side."""

    def __init__(self, probe: Probe, names: tuple[str, ...], sel: np.ndarray | None):
        self.probe, self.names, self.sel = probe, names, sel

    def __call__(self, z: np.ndarray) -> np.ndarray:
        effects = [(LIB[n], v) for n, v in _split(self.names, z).items()]
        return self.probe.residual(effects, self.sel).ravel()

    def __getstate__(self) -> dict:
        return {"names": self.names, "sel": self.sel}

    def __setstate__(self, state: dict) -> None:
        self.__init__(worker_probe(), state["names"], state["sel"])  # type: ignore[misc]


def fit_effects(
    probe: Probe,
    names: Iterable[str],
    sel: np.ndarray,
    warm: dict | None = None,
    blocks: np.ndarray | None = None,
    max_nfev: int = 60,
    workers: Callable | None = None,
) -> Fit:
    """Least-squares fit of the named effects' parameters on the transitions idx[sel]. ``blocks``
    (block id per selected transition) gives cluster-robust standard errors. ``workers``: a
    map-like callable for the Jacobian's columns (processes that hold the probe; the same result
    as without)."""
    names = tuple(names)
    if not names:
        return Fit((), {}, {}, float(np.mean(probe.residual((), sel) ** 2)))
    warm = warm or {}
    lo = np.concatenate([LIB[n].lower for n in names])
    hi = np.concatenate([LIB[n].upper for n in names])
    scale = np.maximum(np.abs(hi - lo) / 20.0, 1e-12)

    def starts():
        base = [np.asarray(warm.get(n, LIB[n].x0), float) for n in names]
        yield np.concatenate(base)
        for j, n in enumerate(names):
            if n not in warm:
                for s in LIB[n].starts:
                    alt = list(base)
                    alt[j] = np.asarray(s, float)
                    yield np.concatenate(alt)

    fun = Objective(probe, names, sel)

    best = None
    for x0 in starts():
        x0 = np.clip(x0, lo, hi)
        try:
            r = least_squares(
                fun,
                x0,
                bounds=(lo, hi),
                x_scale=scale,
                diff_step=1e-4,
                max_nfev=max_nfev,
                method="trf",
                tr_solver="lsmr" if len(x0) > 1 else "exact",
                workers=workers,
            )
        except ValueError:
            continue
        if best is None or r.cost < best.cost:
            best = r
    if best is None:  # every start failed (non-finite residuals): the candidate cannot be fitted
        x = np.concatenate([np.asarray(warm.get(n, LIB[n].x0), float) for n in names])
        unknown = {n: np.diag(np.full(len(LIB[n].params), np.inf)) for n in names}
        inf_se = _split(names, np.full(len(x), np.inf))
        return Fit(names, _split(names, x), inf_se, float("inf"), unknown)
    x = best.x
    cov = _robust_cov(best, blocks)
    if "delay" in names:
        pinned = _whole_pwm_delay(fun, names, best, (lo, hi), scale, probe.ts_s, max_nfev, workers)
        if pinned is not None:
            best, x = pinned
            cov = _robust_cov(best, blocks)
            j = _pwm_index(names)  # the pinned parameter: no variance of its own
            cov = np.insert(np.insert(cov, j, 0.0, axis=0), j, 0.0, axis=1)
    se = np.sqrt(np.maximum(np.diag(cov), 0))
    blk = {}
    p = 0
    for n in names:  # each effect's block of the covariance
        k = len(LIB[n].params)
        blk[n] = cov[p : p + k, p : p + k]
        p += k
    return Fit(
        names, _split(names, x), _split(names, se), float(2 * best.cost / best.fun.size), blk
    )


class Pinned:
    """An objective with one parameter held at a value: the residual at the other parameters
    (pickles as its objective does)."""

    def __init__(self, fun: Objective, j: int, value: float):
        self.fun, self.j, self.value = fun, j, value

    def full(self, z: np.ndarray) -> np.ndarray:
        return np.insert(np.asarray(z, float), self.j, self.value)

    def __call__(self, z: np.ndarray) -> np.ndarray:
        return self.fun(self.full(z))


def _pwm_index(names: tuple[str, ...]) -> int:
    p = 0
    for n in names:
        if n == "delay":
            return p + LIB[n].params.index("pwm_delay_periods")
        p += len(LIB[n].params)
    raise ValueError("no delay among the fitted effects")


def _whole_pwm_delay(fun, names, best, bounds, scale, ts_s, max_nfev, workers):
    """The fit again with the PWM delay held at whole periods (the one below the fitted total
    delay, and the one above when the total is past half a period beyond it), the rest of the
    total as the sample delay, the other parameters free; the better of the two (docs/gap.md,
    "How far"). A rig's PWM update is late by whole periods. A fraction of a period of PWM delay
    shifts the measured increment as the same time of sample delay does (their values correlate
    at -0.99), and the continuous fit drifts to it: it takes no noise of the samples into the
    current it starts from (a sample delay's inversion of the late samples does), but it leaves a
    d-voltage even in speed on the settled plateaus, which was taken for an iron loss (an 8 us
    sample delay as 0.156 periods of PWM delay and a 1450 ohm iron loss). Returns (result, full
    parameter vector), or None when every fit failed."""
    lo, hi = bounds
    j = _pwm_index(names)
    js = j - LIB["delay"].params.index("pwm_delay_periods")  # the sample delay: its first parameter
    total = best.x[js] / ts_s + best.x[j]  # in periods
    whole = np.floor(total + 1e-9)
    wholes = [whole, whole + 1] if total - whole > 0.5 else [whole]
    free = np.arange(len(best.x)) != j
    out = None
    for n in wholes:
        n = float(np.clip(n, lo[j], hi[j]))
        x0 = best.x.copy()
        x0[js] = np.clip((total - n) * ts_s, lo[js], hi[js])
        pin = Pinned(fun, j, n)
        try:
            r = least_squares(
                pin,
                x0[free],
                bounds=(lo[free], hi[free]),
                x_scale=scale[free],
                diff_step=1e-4,
                max_nfev=max_nfev,
                method="trf",
                tr_solver="lsmr" if free.sum() > 1 else "exact",
                workers=workers,
            )
        except ValueError:
            continue
        if out is None or r.cost < out[0].cost:
            out = (r, pin.full(r.x))
    return out


def _robust_cov(r, blocks) -> np.ndarray:
    """Cluster-robust (per block) covariance of a least-squares fit's parameters."""
    J = r.jac
    J = J.toarray() if hasattr(J, "toarray") else np.asarray(J)
    f = r.fun
    try:
        H = np.linalg.pinv(J.T @ J)
    except np.linalg.LinAlgError:
        return np.diag(np.full(J.shape[1], np.inf))
    if blocks is None:
        s2 = float(f @ f) / max(len(f) - J.shape[1], 1)
        return H * s2
    b2 = np.repeat(blocks, 2)  # two residual components per transition
    g = J * f[:, None]
    ub, inv = np.unique(b2, return_inverse=True)
    G = np.zeros((len(ub), J.shape[1]))
    np.add.at(G, inv, g)
    S = G.T @ G * len(ub) / max(len(ub) - 1, 1)
    return H @ S @ H


def block_mse(r: np.ndarray, blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sum of squared residual per block, samples per block) over the block ids in order."""
    ub, inv = np.unique(blocks, return_inverse=True)
    ss = np.zeros(len(ub))
    np.add.at(ss, inv, np.sum(r * r, axis=1) / 2.0)
    cnt = np.bincount(inv, minlength=len(ub)).astype(float)
    return ss, cnt


def bootstrap_closure(
    r_base: np.ndarray,
    r_aug: np.ndarray,
    floor_per_sample: np.ndarray,
    blocks: np.ndarray,
    n_boot: int = 400,
    seed: int = 0,
) -> Closure:
    """Closure (MSE_base - MSE_aug) / (MSE_base - floor) on these samples and a 95 % block-
    bootstrap interval; also the MSE reduction and its interval."""
    sb, cnt = block_mse(r_base, blocks)
    sa, _ = block_mse(r_aug, blocks)
    ub, inv = np.unique(blocks, return_inverse=True)
    fl = np.zeros(len(ub))
    np.add.at(fl, inv, floor_per_sample)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(ub), size=(n_boot, len(ub)))

    def stat(i):
        n = cnt[i].sum(-1)
        mb, ma, mf = sb[i].sum(-1) / n, sa[i].sum(-1) / n, fl[i].sum(-1) / n
        return (mb - ma) / np.maximum(mb - mf, 1e-12 * np.maximum(mb, 1e-30)), mb - ma

    c, d = stat(np.arange(len(ub)))
    cb, db = stat(idx)
    return {
        "closure": float(c),
        "closure_interval": [float(np.percentile(cb, 2.5)), float(np.percentile(cb, 97.5))],
        "mse_gain": float(d),
        "mse_gain_se": float(np.std(db)),
        "mse_gain_interval": [float(np.percentile(db, 2.5)), float(np.percentile(db, 97.5))],
    }
