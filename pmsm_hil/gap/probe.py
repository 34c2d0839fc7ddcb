"""The probe: one-step residuals of the nominal model, optionally augmented (docs/gap.md)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np
from scipy.signal import lfilter

from pmsm_hil.gap.effects import EFFECTS, STAGE_ORDER, Effect, Work, current_sign, dead_time_dist
from pmsm_hil.gap.model import (
    MotorModel,
    PlantTerms,
    abc_to_ab,
    predict_euler,
    predict_rk4,
    rot_cs,
    volts,
)
from pmsm_hil.gap.record import ControlRecord, speed_from_angle


def _shift(x: np.ndarray, n: int, run_start: np.ndarray) -> np.ndarray:
    """x[k - n], held at the start of each run (run_start[k]: index of k's run start)."""
    if n <= 0:
        return x
    j = np.maximum(np.arange(len(x)) - n, run_start)
    return x[j]


class Probe:
    """One-step predictor on a control-rate record. ``idx``: the samples k whose k-1 and k+1 are
    in the same run with the PWM on (the transitions the residual is computed for)."""

    def __init__(self, rec: ControlRecord, motor: MotorModel):
        self.rec, self.m = rec, motor
        n = rec.n
        self.run_start = np.zeros(n, dtype=np.int64)
        first = np.zeros(n, dtype=bool)
        ok = np.zeros(n, dtype=bool)
        for a, b in rec.runs:
            self.run_start[a:b] = a
            first[a] = True
            ok[a + 1 : b - 1] = True
        ok &= rec.pwm_on & np.roll(rec.pwm_on, 1)
        self.first = first
        self.idx = np.nonzero(ok)[0]
        self.ts_s = rec.ts_s
        self._u0 = rec.u_alpha_beta()
        self._c, self._s = np.cos(rec.theta_e_rad), np.sin(rec.theta_e_rad)
        self._iab = abc_to_ab(rec.i_abc)
        # the speed that turns the rotor frame over a period: zero-phase from the angle, not the
        # record's speed column (an observer's speed lags on ramps: a voltage error psi_f d(omega)
        # correlated with the current, which would read as a resistance error)
        self.omega = speed_from_angle(rec.theta_e_rad, rec.omega_e_rad_s, rec.runs, rec.ts_s)
        self._u_cache: list = []  # u_at's last results
        # the last sample-delay inversion: (a, the currents it was made of, the result); the
        # Jacobian's columns of the other parameters ask for the same one again
        self._unblend_cache: tuple[float, np.ndarray, np.ndarray] | None = None
        self._last_i_abc: np.ndarray | None = None  # the last evaluation's currents (work)

    # ------------------------------------------------------------------ evaluation
    def work(self, effects: Iterable[tuple[Effect, np.ndarray]]) -> Work:
        rec = self.rec
        w = Work(
            i_abc=rec.i_abc,
            theta=rec.theta_e_rad,
            omega=self.omega,
            cmd=None if rec.voltage_kind == "alphabeta" else rec.v_cmd,
            kind=rec.voltage_kind,
            v_dc=rec.v_dc_v,
            pwm_on=rec.pwm_on,
            first=self.first,
        )
        ctx = _Ctx(self.ts_s, self.m)
        for eff, x in sorted(effects, key=lambda ex: STAGE_ORDER[ex[0].stage]):
            eff.apply(w, x, ctx)
        # An effect on the sensors (gain, offsets) makes new currents at every evaluation; the same
        # values as the last evaluation's become that array again, so that u_at's cache (keyed by
        # the arrays' identity) serves a fit's columns that move only other parameters
        last = self._last_i_abc
        if w.i_abc is not rec.i_abc:
            if last is not None and last.shape == w.i_abc.shape and np.array_equal(last, w.i_abc):
                w.i_abc = last
            else:
                self._last_i_abc = w.i_abc
        return w

    def u_at(self, w: Work, rows: np.ndarray) -> np.ndarray:
        """The applied alpha-beta voltage over the periods starting at rows (M, 2). The last few
        results are kept: a fit's finite-difference columns that move only the model's parameters
        (saturation, thermal, ...) ask again for the same voltage. The key holds the arrays the
        voltage is computed from (their identity: an effect that changes one makes a new array),
        the dead-time parameters, the PWM delay and the rows."""
        dead = w.extra.get("dead_time")
        key = (
            id(w.cmd),
            id(w.i_abc),
            id(w.v_dc),
            id(w.pwm_on),
            w.kind,
            float(w.pwm_delay),
            None if dead is None else np.asarray(dead, float).tobytes(),
            len(rows),
            hash(rows.tobytes()),
        )
        for k, arrays, u in self._u_cache:
            if k == key and all(
                a is b for a, b in zip(arrays, (w.cmd, w.i_abc, w.v_dc, w.pwm_on), strict=True)
            ):
                return u
        u = self._u_at(w, rows)
        u.flags.writeable = False
        self._u_cache = [(key, (w.cmd, w.i_abc, w.v_dc, w.pwm_on), u), *self._u_cache[:3]]
        return u

    def _u_at(self, w: Work, rows: np.ndarray) -> np.ndarray:
        n_int = int(np.floor(w.pwm_delay))
        frac = w.pwm_delay - n_int
        rs = self.run_start[rows]
        dead = w.extra.get("dead_time")
        if w.cmd is None or dead is None:

            def at(n: int) -> np.ndarray:
                return self._u0[np.maximum(rows - n, rs)]

        else:
            # what both delays' voltages take at the rows, once: the phase currents (leg c carries
            # -(i_a + i_b): i_c need not be measured), the DC link and the currents' smooth sign
            i_ab = w.i_abc[rows, :2]
            i3 = np.column_stack([i_ab, -i_ab.sum(axis=1)])
            at_rows = (i3, w.v_dc[rows], current_sign(i3, dead))

            def at(n: int) -> np.ndarray:
                return self._u_int(w, rows, rs, n, dead, at_rows)

        u = at(n_int)
        if frac > 0:
            u = (1 - frac) * u + frac * at(n_int + 1)
        return u

    def _u_int(self, w: Work, rows, rs, n, dead, at_rows: tuple) -> np.ndarray:
        assert w.cmd is not None
        i3, v_dc, sg = at_rows
        j = np.maximum(rows - n, rs)
        jp = np.maximum(j - 1, rs)
        cmd, prev = w.cmd[j], w.cmd[jp]
        was_off = (~w.pwm_on[jp]) | (jp == j)
        dist = dead_time_dist(
            dead, w.kind, cmd, prev.copy(), i3, v_dc, w.pwm_on[j], was_off, self.ts_s, sg=sg
        )
        v = cmd * v_dc[:, None] + dist
        u = np.stack(
            [(2 * v[:, 0] - v[:, 1] - v[:, 2]) / 3.0, (v[:, 1] - v[:, 2]) / np.sqrt(3.0)], axis=1
        )
        u[~w.pwm_on[j]] = 0.0
        return u

    def _unblended(self, meas_ab: np.ndarray, a: float) -> np.ndarray:
        """The currents at the period boundaries from samples taken a fraction ``a`` of a period
        early, meas(k) = (1 - a) i(k) + a i(k - 1): the blend inverted along each run, from its
        first sample taken as the current then. For a < 1/2 forward, i(k) = (meas(k) -
        a i(k - 1)) / (1 - a); above, backward from the run's last sample, i(k - 1) = (meas(k) -
        (1 - a) i(k)) / a (each direction is the stable one there). Putting meas(k - 1) for
        i(k - 1) instead left an error of a^2 / (1 - a) of the previous increment, which on a
        8 us delay doubled the residual's mean square at the true delay (docs/gap.md, "How
        far")."""
        out = np.empty_like(meas_ab)
        for r0, r1 in self.rec.runs:
            x = meas_ab[r0:r1]
            if len(x) == 0:
                continue
            if a < 0.5:
                b, q = 1.0 / (1.0 - a), a / (1.0 - a)
                out[r0:r1] = lfilter([b], [1.0, q], x, axis=0, zi=(1.0 - b) * x[:1])[0]
            else:  # i(k - 1) from meas(k) and i(k): the run backwards, shifted by one
                b, q = 1.0 / a, (1.0 - a) / a
                xr = x[::-1]
                y = np.empty_like(x)
                y[-1] = x[-1]
                y[:-1] = lfilter([b], [1.0, q], xr[:-1], axis=0, zi=-q * x[-1:])[0][::-1]
                out[r0:r1] = y
        return out

    def residual(
        self,
        effects: Iterable[tuple[Effect, np.ndarray]] = (),
        sel: np.ndarray | None = None,
        euler: bool = False,
    ) -> np.ndarray:
        """Residual (M, 2) in volts-equivalent for idx[sel] (all when None)."""
        k = self.idx if sel is None else self.idx[sel]
        w = self.work(effects)
        m, ts = self.m, self.ts_s
        th0 = w.theta[k]
        d = self.rec.theta_e_rad[0] - w.theta[0]  # an encoder correction shifts the angle
        c0, s0, c1, s1 = self._c[k], self._s[k], self._c[k + 1], self._s[k + 1]
        if d != 0.0:
            cd, sd = np.cos(d), np.sin(d)
            c0, s0 = c0 * cd + s0 * sd, s0 * cd - c0 * sd
            c1, s1 = c1 * cd + s1 * sd, s1 * cd - c1 * sd
        a = w.sample_frac
        i_ab = self._iab if w.i_abc is self.rec.i_abc else None
        if a != 0:  # the true currents at the period boundaries, from the late samples
            c = self._unblend_cache
            if c is None or c[0] != a or c[1] is not w.i_abc:
                full = self._unblended(abc_to_ab(w.i_abc) if i_ab is None else i_ab, a)
                c = self._unblend_cache = (a, w.i_abc, full)
            i0_ab = c[2][k]
            ab_1 = abc_to_ab(w.i_abc[k + 1]) if i_ab is None else i_ab[k + 1]
        elif i_ab is None:
            sub = abc_to_ab(w.i_abc[np.concatenate([k, k + 1])])
            i0_ab, ab_1 = sub[: len(k)], sub[len(k) :]
        else:
            i0_ab, ab_1 = i_ab[k], i_ab[k + 1]
        i0 = rot_cs(i0_ab, c0, -s0)
        om = w.omega[k]
        if euler:
            pred = predict_euler(m, i0, th0, om, self.u_at(w, k), ts)
        else:
            pt = PlantTerms(
                r_s_ohm=m.r_s_ohm * w.r_scale,
                psi_f_wb=m.psi_f_wb * w.psi_scale,
                sat=w.sat,
                g_fe_s=w.g_fe_s,
            )
            if w.harm is not None:
                pt.psi_h_dq = _harmonic_flux(m.psi_f_wb, w.harm, th0 + 0.5 * om * ts)
            mp = m
            if "l_scale" in w.extra:
                mp = replace(
                    m, l_d_h=m.l_d_h * w.extra["l_scale"][0], l_q_h=m.l_q_h * w.extra["l_scale"][1]
                )
            pred = predict_rk4(mp, i0, th0, om, self.u_at(w, k), ts, pt, cs0=(c0, s0))
        if a != 0:
            pred = rot_cs((1 - a) * rot_cs(pred, c1, s1) + a * i0_ab, c1, -s1)
        meas1 = rot_cs(ab_1, c1, -s1)
        return volts(m, meas1 - pred, ts)


class _Ctx:
    def __init__(self, ts_s, m):
        self.ts_s, self.m = ts_s, m


def _harmonic_flux(psi_f, harm, theta):
    """psi_h in dq and d psi_h / d theta for the 5th/7th harmonics (a5, a7 complex, relative EMF)."""
    a5, a7 = harm
    e6p, e6m = np.exp(6j * theta), np.exp(-6j * theta)
    ph = psi_f * (a7 / 7 * e6p + a5 / 5 * e6m)
    dph = psi_f * (6j * a7 / 7 * e6p - 6j * a5 / 5 * e6m)
    return np.stack([ph.real, ph.imag], -1).T, np.stack([dph.real, dph.imag], -1).T


def current_range(probe: Probe) -> dict[str, list[float]]:
    """The dq currents the record's transitions span (0.5 and 99.5 percentiles, so that a spike
    does not widen it): where a fitted saturation model was fitted, and where a flux map written
    from it (gap augment) may follow it (rigfile.py)."""
    k = probe.idx
    i_dq = rot_cs(probe._iab[k], probe._c[k], -probe._s[k])
    lo, hi = np.percentile(i_dq, [0.5, 99.5], axis=0)
    return {"i_d_a": [float(lo[0]), float(hi[0])], "i_q_a": [float(lo[1]), float(hi[1])]}


def mse(r: np.ndarray) -> float:
    return float(np.mean(r * r)) if len(r) else float("nan")


def effect_list(names_x: dict) -> list:
    return [(EFFECTS[n], np.asarray(x, float)) for n, x in names_x.items()]
