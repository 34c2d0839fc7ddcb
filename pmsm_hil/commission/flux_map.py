"""The flux map by commissioning (`pmsm-hil commission --flux-map`, docs/commissioning.md).

After the firmware's sequence, the host plays a profile on the commissioned motor: FOC (smooth
voltages that telemetry samples without aliasing), i_d by the segment's square-wave excitation
(half the segment at +a, half at -a; one segment at a = 0), i_q from the load the speed loop holds
against, every operating point at two speeds. In steady state

    u_d = R i_d - w psi_q(i_d, i_q) + e_d(i),    u_q = R i_q + w psi_d(i_d, i_q) + e_q(i),

where e is what the inverter does that the firmware's compensation misses. At the same currents
the difference between the two speeds leaves the flux alone:

    psi_d = [(u_q - R i_q)_2 - (u_q - R i_q)_1] / (w_2 - w_1), psi_q likewise with -u_d,

so neither R nor the inverter's residual enters (R only through the small change of the currents
between the speeds). Telemetry's u_d, u_q are the voltage applied over the period at the angle of
its start: they are turned by w Ts / 2 to the period's middle first.
"""

from __future__ import annotations

import datetime as _dt
import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pmsm_hil.log.reader import Log
from pmsm_hil.profiles import Motor, Profile, load_profile
from pmsm_hil.profiles.fluxmap import FluxMap

SETTLE_FRAC = 0.6  # each half segment: the first 60 % settles, the rest is averaged
HALF_S = 0.4  # one operating point


@dataclass(frozen=True)
class MapPlan:
    speeds_rpm: tuple[float, float]
    loads_nm: tuple[float, ...]
    i_d_steps_a: tuple[float, ...]  # excitation amplitudes; 0 gives the i_d = 0 point

    @property
    def n_points(self) -> int:
        n_id = sum(1 if a == 0 else 2 for a in self.i_d_steps_a)
        return n_id * len(self.loads_nm)


@dataclass(frozen=True)
class MapPoint:
    i_d_a: float
    i_q_a: float
    psi_d_wb: float
    psi_q_wb: float
    load_nm: float
    i_d_cmd_a: float


def plan_for(motor: Motor, speeds_rpm: Sequence[float] | None = None) -> MapPlan:
    """Five i_d levels over +-half the current limit, five loads over +-half the torque limit,
    at 30 % and 60 % of the speed limit (unless given)."""
    if speeds_rpm is None:
        n = 0.5 * motor.speed_max_rpm
        speeds = (-n, n)
    else:
        if len(speeds_rpm) != 2:
            raise ValueError(f"the flux map needs two speeds, got {list(speeds_rpm)}")
        speeds = (float(speeds_rpm[0]), float(speeds_rpm[1]))
    lo, hi = speeds
    if not (lo < hi and lo != 0 and hi != 0 and max(abs(lo), abs(hi)) <= motor.speed_max_rpm):
        raise ValueError(
            f"flux-map speeds {lo:g}, {hi:g} r/min: need two different, non-zero speeds within "
            f"the motor's speed_max_rpm {motor.speed_max_rpm:g}"
        )
    t = 0.5 * motor.torque_max_nm
    a = 0.25 * motor.i_max_a
    return MapPlan(
        speeds_rpm=(lo, hi), loads_nm=(-t, -0.5 * t, 0.0, 0.5 * t, t), i_d_steps_a=(0.0, a, 2 * a)
    )


def _segments(plan: MapPlan) -> list[str]:
    segs = []
    for n in plan.speeds_rpm:
        segs.append(
            f"  - {{name: 'to {n:.0f} r/min', duration_s: {abs(n) / 1000.0 + 0.5:.3f}, "
            f"speed_rpm: {n:.6g}, ramp_rpm_s: 2000, estimate: false}}"
        )
        for load in plan.loads_nm:
            for a in plan.i_d_steps_a:
                dur = HALF_S if a == 0 else 2 * HALF_S
                hz = 0.0 if a == 0 else 1.0 / dur
                segs.append(
                    f"  - {{name: 'map {n:.0f} r/min {load:+.3g} N m i_d +-{a:.3g} A', "
                    f"duration_s: {dur:g}, speed_rpm: {n:.6g}, load_nm: {load:.6g}, "
                    f"inject_a: {a:.6g}, inject_hz: {hz:.6g}, estimate: false}}"
                )
    segs.append("  - {name: stop, duration_s: 1.0, speed_rpm: 0, ramp_rpm_s: 2000}")
    return segs


def flux_map_profile(
    motor_path: str | Path, rig_path: str | Path, plan: MapPlan, ts_s: float
) -> Profile:
    """The measuring profile on the (commissioned) motor file and the commissioning's rig."""
    text = (
        "name: flux-map\n"
        "description: steady-state points for the flux map (pmsm-hil commission --flux-map)\n"
        f"motor: {Path(motor_path).resolve()}\n"
        f"rig: {Path(rig_path).resolve()}\n"
        "control:\n"
        f"  ts_s: {ts_s!r}\n"
        "  current_ctrl: foc\n"
        "  current_ref: id_zero\n"
        "  dead_time_comp: true\n"
        "telemetry: {fast_hz: 2000, params_hz: 10, status_hz: 10, truth_hz: 100}\n"
        "segments:\n" + "\n".join(_segments(plan)) + "\n"
    )
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "flux-map.yaml"
        p.write_text(text)
        return load_profile(p)


def _window_means(tel: dict, t0: float, t1: float) -> dict[str, float] | None:
    t = np.asarray(tel["t_s"], float)
    a = t0 + SETTLE_FRAC * (t1 - t0)
    m = (t >= a) & (t < t1)
    if m.sum() < 10:
        return None
    return {k: float(np.mean(np.asarray(tel[k], float)[m])) for k in tel if k != "t_s"}


def measure(log: Log, plan: MapPlan, motor: Motor, ts_s: float) -> list[MapPoint]:
    """The map's points from a flux-map run's log (a `read_log` result)."""
    tel = log.topic("/pmsm/telemetry")
    ev = log.topic("/pmsm/events")
    starts = {
        int(arg): float(t)
        for t, kind, arg in zip(ev["t_s"], ev["kind"], ev["arg"], strict=True)
        if str(kind) == "segment_start"
    }
    p = motor.pole_pairs
    per_speed: list[dict[tuple[int, float], dict[str, float]]] = []
    seg = 0
    for _n in plan.speeds_rpm:
        seg += 1  # the ramp
        got: dict[tuple[int, float], dict[str, float]] = {}
        for li, _load in enumerate(plan.loads_nm):
            for a in plan.i_d_steps_a:
                t0 = starts.get(seg)
                seg += 1
                if t0 is None:
                    continue
                halves = (
                    [(a, t0, t0 + HALF_S)]
                    if a == 0
                    else [(a, t0, t0 + HALF_S), (-a, t0 + HALF_S, t0 + 2 * HALF_S)]
                )
                for level, h0, h1 in halves:
                    w = _window_means(tel, h0, h1)
                    if w is not None:
                        got[(li, level)] = w
        per_speed.append(got)
    r = motor.r_s_ohm
    points = []
    for key, w1 in per_speed[0].items():
        w2 = per_speed[1].get(key)
        if w2 is None:
            continue
        terms = []
        for w in (w1, w2):
            we = w["speed_rpm"] * p * math.pi / 30.0
            ph = 0.5 * we * ts_s  # to the middle of the period
            u_d = w["u_d_v"] * math.cos(ph) + w["u_q_v"] * math.sin(ph)
            u_q = -w["u_d_v"] * math.sin(ph) + w["u_q_v"] * math.cos(ph)
            terms.append((we, u_d - r * w["i_d_a"], u_q - r * w["i_q_a"]))
        (we1, xd1, xq1), (we2, xd2, xq2) = terms
        if abs(we2 - we1) < 1.0:
            continue
        li, level = key
        points.append(
            MapPoint(
                i_d_a=0.5 * (w1["i_d_a"] + w2["i_d_a"]),
                i_q_a=0.5 * (w1["i_q_a"] + w2["i_q_a"]),
                psi_d_wb=(xq2 - xq1) / (we2 - we1),
                psi_q_wb=-(xd2 - xd1) / (we2 - we1),
                load_nm=plan.loads_nm[li],
                i_d_cmd_a=level,
            )
        )
    return sorted(points, key=lambda q: (q.i_d_cmd_a, q.i_q_a))


def grid(points: Sequence[MapPoint]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The points on a regular grid (the flux-map CSV's form): i_d nodes at the commanded levels,
    i_q nodes evenly spaced over the measured range (as many as loads); each i_d level is
    interpolated along i_q within its own measured range, nodes outside it are NaN (missing)."""
    levels = np.array(sorted({q.i_d_cmd_a for q in points}))
    iq_all = np.array([q.i_q_a for q in points])
    n_q = max(2, round(len(points) / max(len(levels), 1)))
    iq_nodes = np.linspace(iq_all.min(), iq_all.max(), n_q)
    pd = np.full((n_q, len(levels)), np.nan)
    pq = np.full((n_q, len(levels)), np.nan)
    for j, lv in enumerate(levels):
        col = sorted((q for q in points if q.i_d_cmd_a == lv), key=lambda q: q.i_q_a)
        if len(col) < 2:
            continue
        x = np.array([q.i_q_a for q in col])
        inside = (iq_nodes >= x[0] - 1e-9) & (iq_nodes <= x[-1] + 1e-9)
        pd[inside, j] = np.interp(iq_nodes[inside], x, [q.psi_d_wb for q in col])
        pq[inside, j] = np.interp(iq_nodes[inside], x, [q.psi_q_wb for q in col])
    return levels, iq_nodes, pd, pq


def csv_text(points: Sequence[MapPoint], device: str, now: _dt.datetime | None = None) -> str:
    levels, iq_nodes, pd, pq = grid(points)
    stamp = (now or _dt.datetime.now(_dt.UTC)).strftime("%Y-%m-%dT%H:%M:%SZ")
    lines = [
        f"# Flux map measured by `pmsm-hil commission --flux-map` on {stamp} ({device}).",
        f"# {len(points)} steady-state points at two speeds (docs/commissioning.md), on a "
        f"{len(levels)} x {len(iq_nodes)} grid; nodes outside the measured range are left out.",
        "i_d_a,i_q_a,psi_d_wb,psi_q_wb",
    ]
    for k, iq in enumerate(iq_nodes):
        for j, idd in enumerate(levels):
            if np.isfinite(pd[k, j]) and np.isfinite(pq[k, j]):
                lines.append(f"{idd:.10g},{iq:.10g},{pd[k, j]:.6g},{pq[k, j]:.6g}")
    return "\n".join(lines) + "\n"


def truth_map(profile: Profile) -> FluxMap | None:
    """The map the emulator's plant follows: the rig's saturation effect's, else the motor's,
    else None (a linear plant)."""
    from pmsm_hil.profiles.fluxmap import load_flux_map

    rig = profile.rig
    if rig.effects.saturation.enabled:
        return rig.flux_map()
    path = profile.motor.flux_map_path()
    return load_flux_map(path) if path else None


def errors_against(
    points: Sequence[MapPoint], fm: FluxMap | None, linear: tuple[float, float, float]
) -> dict:
    """Measured minus true flux at the measured currents, in Wb: rms and worst per axis. `fm` is
    the plant's map (None: linear); `linear` = (psi_f_wb, l_d_h, l_q_h) of /sim/truth during the
    run. With a map the plant adds the magnet's temperature shift, psi_f now minus the map's
    psi_d(0, 0), to psi_d; so does the truth here."""
    i_d = np.array([q.i_d_a for q in points])
    i_q = np.array([q.i_q_a for q in points])
    if fm is not None:
        from scipy.interpolate import RegularGridInterpolator

        # cubic inside the map, linear beyond its edges (as the plant extends it)
        xy = np.column_stack([i_q, i_d])
        axes = (fm.i_q_a, fm.i_d_a)
        inside = (
            (i_q >= fm.i_q_a[0])
            & (i_q <= fm.i_q_a[-1])
            & (i_d >= fm.i_d_a[0])
            & (i_d <= fm.i_d_a[-1])
        )
        td = RegularGridInterpolator(axes, fm.psi_d_wb, bounds_error=False, fill_value=None)(xy)
        tq = RegularGridInterpolator(axes, fm.psi_q_wb, bounds_error=False, fill_value=None)(xy)
        if inside.any():
            td[inside] = RegularGridInterpolator(axes, fm.psi_d_wb, method="cubic")(xy[inside])
            tq[inside] = RegularGridInterpolator(axes, fm.psi_q_wb, method="cubic")(xy[inside])
        psi_map0 = RegularGridInterpolator(axes, fm.psi_d_wb, method="cubic")([[0.0, 0.0]])[0]
        td = td + (linear[0] - psi_map0)
    else:
        psi_f, l_d, l_q = linear
        td = psi_f + l_d * i_d
        tq = l_q * i_q
    ed = np.array([q.psi_d_wb for q in points]) - td
    eq = np.array([q.psi_q_wb for q in points]) - tq
    return {
        "n": len(points),
        "psi_d_rms_wb": float(np.sqrt(np.mean(ed**2))),
        "psi_d_max_wb": float(np.max(np.abs(ed))),
        "psi_q_rms_wb": float(np.sqrt(np.mean(eq**2))),
        "psi_q_max_wb": float(np.max(np.abs(eq))),
    }
