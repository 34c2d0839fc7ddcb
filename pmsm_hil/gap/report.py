"""The diagnosis's outputs: the terminal verdict, JSON, and a report directory (plots + HTML)."""

from __future__ import annotations

import html
import json
import os

import numpy as np


def jsonable(x: object) -> object:
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    return x


def _fmt(v):
    if v is None:
        return "-"
    return f"{v:.3g}"


def closure_text(v: float | None) -> str:
    """A closure for the console: beyond [-1, 10] it only says that the gap above the noise floor
    is within the floor's own error (the ratio's denominator near zero: it once printed 3.6e10)."""
    if v is None:
        return "-"
    if v < -1:
        return "< -1"
    return "> 10" if v > 10 else f"{v:.2f}"


def steady_lines(res: dict) -> list[str]:
    """The verdict of steady-state dq data (pmsm_hil.gap.steady): the fitted constant values are in
    the verdict itself; then the gap, the motor file's values and what was not assessed."""
    p, b = res["parametric_gap"], res["base_gap"]
    nom = p.get("motor_file") or {}
    out = [
        f"gap: {res['verdict']}",
        f"  {res['samples']} steady-state operating points; base gap {b['rms_v']:.3g} V rms "
        f"(u_d, u_q against the motor file), {np.sqrt(max(p['mse_after_v2'], 0)):.3g} V rms with "
        "the fitted values",
    ]
    if nom:
        out.append(
            f"  motor file: R {nom['r_s_ohm']:.4g} ohm, Ld {nom['l_d_h'] * 1e3:.4g} mH, "
            f"Lq {nom['l_q_h'] * 1e3:.4g} mH, psi_f {nom['psi_f_wb']:.4g} Wb"
        )
    de = res.get("d_axis_emf")
    if de:
        lo, hi = de["interval_95"]
        out.append(
            f"  a d-axis voltage in proportion to speed that the model has not: psi_q at zero "
            f"current {de['psi_q0_wb'] * 1e3:.3g} mWb [{lo * 1e3:.3g}, {hi * 1e3:.3g}], or an "
            f"angle offset of {de['angle_offset_rad'] * 1e3:.3g} mrad (electrical)"
        )
    th = res.get("thermal")
    if th:
        out.append(
            f"  R against the winding temperature: {th['r_s_ohm_per_k']:.3g} ohm/K "
            f"(alpha {th['alpha_r_per_k']:.3g} 1/K at 25 degC)"
        )
    for part, why in (res.get("not_assessed") or {}).items():
        out.append(f"  not assessed: {part.replace('_', ' ')} ({why})")
    return out


def _rms_step(d: dict) -> str:
    """How much larger the Euler predictor's residual is than RK4's, in V rms (signed)."""
    if "mse_euler_v2" not in d or "mse_rk4_v2" not in d:
        return "?"
    e, r = float(d["mse_euler_v2"]), float(d["mse_rk4_v2"])
    return f"{np.sqrt(max(e, 0.0)) - np.sqrt(max(r, 0.0)):+.3g}"


def _floor_text(res: dict) -> str:
    """The noise floor and where it came from; a floor estimated from the data as zero is said to
    be no estimate: what is left of the residual is correlated from one period to the next (as
    an unmodelled effect leaves it), which the lag-1 estimate cannot tell from sensor noise."""
    fl = float(res["noise_floor_v2"])
    if fl <= 0.0 and not str(res["noise_floor_source"]).startswith("sensor"):
        return (
            "noise floor not estimable from the data (the residual left is correlated from one "
            "period to the next, not sensor noise: an effect outside the library, or a record "
            "too short); the closures are against a floor of zero"
        )
    return f"noise floor {np.sqrt(fl):.3g} V rms ({res['noise_floor_source']})"


def verdict_lines(res: dict) -> list[str]:
    if "discretisation_gap" not in res:  # steady-state dq data
        return steady_lines(res)
    b, d = res["base_gap"], res["discretisation_gap"]
    out = [
        f"gap: {res['verdict']}",
        f"  base gap {b['rms_v']:.3g} V rms one-step residual; {_floor_text(res)}; "
        f"discretisation gap (Euler vs RK4) {_rms_step(d)} V rms ({d['excess_v2']:.3g} V^2)",
    ]
    c = res["closure"]
    if res["selected"]:
        out.append(
            f"  held-out closure {closure_text(c['closure'])} [{closure_text(c['closure_interval'][0])}, {closure_text(c['closure_interval'][1])}] (test blocks)"
            + (
                f", {closure_text(res['closure_region']['closure'])} (held-out speed region)"
                if "closure_region" in res
                else ""
            )
            + (
                f", {closure_text(res['closure_record']['closure'])} (held-out record)"
                if "closure_record" in res
                else ""
            )
        )
    for e in res["effects"]:
        if e.get("selected"):
            iv = e.get("interval") or [None, None]
            out.append(
                f"  + {e['name']}: {e['quantity']} = {_fmt(e['magnitude'])} [{_fmt(iv[0])}, {_fmt(iv[1])}]; {e['evidence']}"
            )
    for a in res.get("ambiguous", []):
        out.append(
            f"  ? {a['effects'][0]} and {a['effects'][1]} cannot be told apart on this data: {a['experiment']}"
        )
    nb = res.get("below_threshold")
    if nb:
        z = nb["gain_v2"] / nb["gain_se_v2"]
        seen = f"  ~ {nb['effect']}: held-out MSE down {nb['gain_v2']:.3g} V^2 ({z:.0f} standard errors), "
        if nb.get("left_v2"):  # refused for its share of what was left (LEFT_REL)
            out.append(
                seen
                + f"{100 * nb['gain_v2'] / nb['left_v2']:.2g} % of the {nb['left_v2']:.3g} V^2 "
                f"left above the floor (at least {100 * nb['left_rel']:.2g} % asked): not named; "
                "what is left is mostly something else, of which it takes a sliver"
            )
        else:
            out.append(
                seen
                + f"under the practical threshold {nb['threshold_v2']:.3g} V^2: not named; the "
                "data may hold it, partly carried by an effect named above"
                + (f" ({nb['experiment']})" if nb["experiment"] else "")
            )
    pl = res.get("plateaus") or {}
    if "rms_before_v" in pl:
        b4, af = pl["rms_before_v"], pl["rms_after_v"]
        out.append(
            f"  settled plateaus: {pl['plateaus']}, mean residual d / q {b4[0]:.2f} / {b4[1]:.2f} V rms"
            + (
                f" -> {af[0]:.2f} / {af[1]:.2f} V with {' + '.join(pl['selected'])}"
                if pl.get("selected")
                else " (nothing taken)"
            )
        )
    elif pl.get("note"):
        out.append(f"  settled plateaus: {pl['note']}")
    p = res["parametric_gap"]
    out.append(
        f"  parametric (best constant values): R {p['r_s_ohm']:.3g} ohm, Ld {p['l_d_h'] * 1e3:.3g} mH, "
        f"Lq {p['l_q_h'] * 1e3:.3g} mH, psi_f {p['psi_f_wb']:.4g} Wb (closure alone {p['closure']:.2f})"
    )
    return out


def _interval(iv) -> str:
    """An interval as the console prints it ([lo, hi], 3 significant digits), or nothing."""
    if not iv or all(v is None for v in iv):
        return ""
    return html.escape(f"[{_fmt(iv[0])}, {_fmt(iv[1])}]")


def _magnitude_cell(e: dict) -> str:
    """A selected effect's magnitude as it is; another's in grey, marked as fitted alone (a table
    of bare numbers read as measurements: a dead time of 1.3e-14 s, iron loss 10 ohm)."""
    value = _fmt(e.get("magnitude"))
    if e.get("selected"):
        return value
    return f"<span style='color:#888'>{value} (alone)</span>"


def write_report(res: dict, out_dir: str | os.PathLike) -> list[str]:
    """gap.json, residual-map plots and index.html in out_dir; returns the files written. A
    steady-state result (pmsm_hil.gap.steady) has no residual maps and no effects: the page states
    what was not assessed and why (its ``not_assessed``)."""
    os.makedirs(out_dir, exist_ok=True)
    files = []
    with open(os.path.join(out_dir, "gap.json"), "w") as f:
        json.dump(jsonable(res), f, indent=1)
    files.append("gap.json")
    if "where" in res:
        files += _plots(res, out_dir)
    rows = "".join(
        f"<tr><td>{html.escape(e['name'])}</td><td>{'yes' if e.get('selected') else ''}</td>"
        f"<td>{html.escape(str(e.get('quantity')))}</td><td>{_magnitude_cell(e)}</td>"
        f"<td>{_interval(e.get('interval'))}</td><td>{_fmt(e.get('closure'))}</td>"
        f"<td>{html.escape(e.get('evidence', ''))}</td></tr>"
        for e in res.get("effects", [])
    )
    page = (
        f"<html><head><meta charset='utf-8'><title>gap</title></head><body><h1>Sim-to-real gap</h1>"
        f"<pre>{html.escape(chr(10).join(verdict_lines(res)))}</pre>"
        + (
            f"<table border=1><tr><th>effect</th><th>selected</th><th>quantity</th>"
            f"<th>magnitude</th><th>interval</th><th>closure</th><th>evidence</th></tr>{rows}</table>"
            "<p><small>magnitude: of a selected effect, the fit beside the other selected ones; "
            "of an effect not selected, grey, what it reached fitted alone, often at a bound of "
            "its range (a dead time of 1e-14 s, a thermal rise of 200 K): not a finding.</small></p>"
            if "effects" in res
            else ""
        )
        + "".join(f"<p><img src='{f}'></p>" for f in files if f.endswith(".png"))
        + "</body></html>"
    )
    with open(os.path.join(out_dir, "index.html"), "w") as f:
        f.write(page)
    files.append("index.html")
    return files


def _plots(res: dict, out_dir: str | os.PathLike) -> list[str]:
    """The residual maps and the order spectrum (control-rate data); returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    where = res["where"]
    files = []
    keys = ["speed", "current", "current_angle", "electrical_angle", "current_sign_sector", "time"]
    xlabels = {
        "speed": "|ω_e| (rad/s)",
        "current": "|i| (A)",
        "current_angle": "current angle (rad)",
        "electrical_angle": "θ_e (rad)",
        "current_sign_sector": "sector: the sign pattern of i_a, i_b, i_c",
        "time": "t (s)",
    }
    fig, axs = plt.subplots(2, 3, figsize=(12, 6))
    for ax, key in zip(axs.ravel(), keys, strict=False):
        for name, style in (("base", "o-"), ("augmented", "s--")):
            rows = where[name][key]
            x = [(r["lo"] + r["hi"]) / 2 for r in rows]
            y = [  # an empty bin (no sample there, e.g. a sign sector that cannot occur): a gap
                np.nan
                if r["rms_d_v"] is None and r["rms_q_v"] is None
                else np.hypot(r["rms_d_v"] or 0, r["rms_q_v"] or 0) / np.sqrt(2)
                for r in rows
            ]
            ax.plot(x, y, style, label=name)
        ax.set_xlabel(xlabels[key], fontsize=8)
        ax.axhline(
            np.sqrt(max(res["noise_floor_v2"], 0)), color="k", lw=0.8, ls=":", label="noise floor"
        )
        ax.set_title(key.replace("_", " "))
        ax.set_ylabel("residual rms, V")
    axs[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "residual_maps.png"), dpi=90)
    plt.close(fig)
    files.append("residual_maps.png")
    spec = where["base"]["order_spectrum"]
    if spec:
        fig, ax = plt.subplots(figsize=(7, 4))
        for row in spec:
            orders = sorted(int(o) for o in row["orders"])
            amp = [np.hypot(*row["orders"][str(o)]) for o in orders]
            ax.plot(
                orders,
                amp,
                "o-",
                label=f"|omega_e| {row['speed_lo_rad_s']:.0f}-{row['speed_hi_rad_s']:.0f} rad/s",
            )
        ax.set_xlabel("order of the electrical angle")
        ax.set_ylabel("amplitude (d and q harmonics combined), V")
        ax.set_title(
            "Base residual (the nominal model, before any effect) by harmonic of θ_e, "
            "per speed quartile",
            fontsize=9,
        )
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(out_dir, "order_spectrum.png"), dpi=90)
        plt.close(fig)
        files.append("order_spectrum.png")
    return files
