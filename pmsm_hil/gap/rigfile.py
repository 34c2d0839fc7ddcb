"""`pmsm-hil gap augment`: the fitted effects as a rig file (format: docs/profiles.md, docs/rigs.md)."""

from __future__ import annotations

import os

import numpy as np
import yaml

from pmsm_hil.files import write_text_whole
from pmsm_hil.gap.model import MotorModel

# how far beyond the currents the record spans the fitted saturation model is followed, as a
# fraction of i_max (beyond: its incremental inductances at that edge, held)
RANGE_MARGIN = 0.1


def _flux_map_csv(
    path: str, m: MotorModel, k: dict, current_range: dict[str, list[float]] | None = None
) -> None:
    """The fitted saturation as a flux map (the probe's saturation model on a 15 x 15 grid).

    The model is followed only over the currents the record spans (``current_range``, the
    diagnosis's `current_range_a`, widened by RANGE_MARGIN of i_max and to zero); beyond, the flux
    goes on with the incremental inductances at that edge. Extrapolated, a fitted cross-saturation
    term turned the incremental inductance negative (the SEW rig's fit: d psi_q / d i_q < 0 at
    i_d = -5 A, i_q = 14 A, where the record never went), and the fitted rig's run tripped
    over_current when its load came on."""
    from pmsm_hil.gap.model import PlantTerms, _flux

    i_max = m.i_max_a
    step = max(0.5, round(1.2 * i_max / 7 * 2) / 2)  # a grid the rig loader sees as regular
    g = np.arange(-7, 8) * step
    pt = PlantTerms(sat=(k["k_d"], k["i_sd_a"], k["k_q"], k["i_sq_a"], k["k_x"], k["k_c"]))
    box = []
    for axis in ("i_d_a", "i_q_a"):
        lo, hi = (current_range or {}).get(axis, (g[0], g[-1]))
        box.append((min(lo, 0.0) - RANGE_MARGIN * i_max, max(hi, 0.0) + RANGE_MARGIN * i_max))
    lines = [
        "# flux map fitted by pmsm-hil gap augment (docs/gap.md): the probe's saturation model over "
        f"i_d {box[0][0]:.3g}..{box[0][1]:.3g} A, i_q {box[1][0]:.3g}..{box[1][1]:.3g} A (the "
        "record's currents), its incremental inductances held beyond",
        "i_d_a,i_q_a,psi_d_wb,psi_q_wb",
    ]
    for iq in g:
        for id_ in g:
            inside = np.array([np.clip(id_, *box[0]), np.clip(iq, *box[1])])
            (pd, pq), (ldd, ldq, lqq) = _flux(m, inside, pt, m.psi_f_wb)
            dd, dq = id_ - inside[0], iq - inside[1]
            pd, pq = pd + ldd * dd + ldq * dq, pq + ldq * dd + lqq * dq
            lines.append(f"{float(id_)!r},{float(iq)!r},{float(pd):.10g},{float(pq):.10g}")
    write_text_whole(path, "\n".join(lines) + "\n")


def rig_delay(p: dict, ts_s: float) -> tuple[dict[str, float | int], str]:
    """The fitted delay as a rig takes it: the same total delay (sample delay + PWM delay x Ts, the
    magnitude the diagnosis quotes), its PWM part in whole periods (a rig's PWM update is late by
    whole periods) and the rest as the sample delay. The one-step residual cannot tell a fraction
    of a period of PWM delay from the same time of sample delay (both shift the measured current's
    increment alike; their fitted values correlate at -0.99), so the fraction moves to the sample
    delay rather than being dropped. Returns the rig parameters and a note (empty when nothing
    moved)."""
    sample_s = max(float(p["sample_delay_s"]), 0.0)
    periods = max(float(p["pwm_delay_periods"]), 0.0)
    total_s = sample_s + periods * ts_s
    whole = min(round(periods), int(np.floor(total_s / ts_s + 1e-9)))
    rig_sample_s = max(sample_s + (periods - whole) * ts_s, 0.0)
    note = ""
    if abs(periods - whole) > 1e-3:
        note = (
            f"delay: the fitted PWM delay of {periods:.3f} periods is written as {whole} and the "
            f"sample delay as {rig_sample_s:.3g} s (fitted {sample_s:.3g} s), so that the total "
            f"{total_s:.3g} s is the one the diagnosis quotes (a rig's PWM update is late by whole "
            "periods; a fraction of a period of it and a sample delay are alike to the diagnosis)"
        )
    return {"sample_delay_s": rig_sample_s, "pwm_delay_periods": whole}, note


def fitted_rig(
    result: dict,
    m: MotorModel,
    out_path: str | os.PathLike,
    sensor_spec: dict[str, float] | None = None,
) -> dict:
    """Write the rig file for the selected effects; returns the mapping written."""
    eff: dict[str, dict] = {}
    spec = sensor_spec or {}
    if spec.get("i_noise_a"):
        eff["adc_noise"] = {"i_noise_a": float(spec["i_noise_a"])}
    if spec.get("adc_lsb_a"):
        eff["adc_quantisation"] = {"adc_lsb_a": float(spec["adc_lsb_a"])}
    notes = []
    why = (result.get("not_assessed") or {}).get("fitted_rig")
    if why:  # steady-state dq data: no effect was fitted
        notes.append(why)
    for e in result.get("effects", []):
        if not e.get("selected"):
            continue
        p = dict(e.get("parameters") or {})
        n = e["name"]
        if n == "delay":
            p, note = rig_delay(p, float(result["ts_s"]))  # a control-rate result's period
            if note:
                notes.append(note)
        elif n == "encoder":
            p = {
                "lines": int(spec.get("encoder_lines", 2500) or 2500),
                "offset_e_rad": p["offset_e_rad"],
            }
        elif n == "saturation":
            map_name = os.path.splitext(os.path.basename(os.fspath(out_path)))[0] + "-map.csv"
            _flux_map_csv(
                os.path.join(os.path.dirname(os.fspath(out_path)) or ".", map_name),
                m,
                p,
                result.get("current_range_a"),
            )
            p = {"map": map_name}
        elif n == "iron_loss":
            p = {"r_fe_ohm": float(min(p["r_fe_ohm"], 1e6))}
        elif n == "thermal":
            p = {k: float(v) for k, v in p.items()}
        elif n == "dc_link":
            notes.append(
                "dc_link: the ripple was seen in the measured v_dc but not fitted; add it by hand"
            )
            continue
        elif n == "cogging":
            p = {
                "amplitude_nm": float(p["amplitude_nm"]),
                "periods_per_rev": int(p["periods_per_rev"]),
                "phase_rad": float(p.get("phase_rad", 0.0)),
            }
        elif n == "friction":
            p = {
                "t_coulomb_nm": max(float(p["t_coulomb_nm"]), 0.0),
                "b_visc_nms": max(float(p["b_visc_nms"]), 0.0),
            }
        eff[n] = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in p.items()}
    if "encoder" not in eff and spec.get("encoder_lines"):
        eff["encoder"] = {"lines": int(spec["encoder_lines"]), "offset_e_rad": 0.0}
    rig = {
        "name": "fitted",
        "description": "Effects fitted by pmsm-hil gap augment: "
        + (", ".join(e["name"] for e in result.get("effects", []) if e.get("selected")) or "none"),
        "v_dc_v": None,
        "effects": eff,
    }
    head = "# Written by `pmsm-hil gap augment` (docs/gap.md). Format: docs/rigs.md.\n"
    head += "".join(f"# {n}\n" for n in notes)
    write_text_whole(out_path, head + yaml.safe_dump(rig, sort_keys=False))
    return rig
