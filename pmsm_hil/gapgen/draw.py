"""Hidden effects and random profiles for the gap self-test: magnitudes log-uniform over the
literature ranges below (the source of each range beside it), profiles drawn independently of them."""

from __future__ import annotations

import numpy as np

TS_S = 50e-6
LSB_A = 100.0 / 4096.0

# every trial's rig has the sensors of a real drive (their specification is given to the diagnoser)
BASE_SENSORS = {
    "adc_noise": {"i_noise_a": 0.02},
    "adc_quantisation": {"adc_lsb_a": LSB_A},
    "encoder": {"lines": 2500, "offset_e_rad": 0.0},
}
SENSOR_SPEC = {"i_noise_a": 0.02, "adc_lsb_a": LSB_A, "encoder_lines": 2500.0}


def _lu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _sign(rng: np.random.Generator) -> float:
    return float(rng.choice([-1.0, 1.0]))


def draw_effect(rng: np.random.Generator, name: str) -> dict:
    """Rig parameters of one effect (docs/rigs.md)."""
    if name == "dead_time":  # IGBT modules: 0.5-4 us blanking, 0.7-2 V drops
        return {
            "dead_time_s": _lu(rng, 0.5e-6, 4e-6),
            "v_drop_v": _lu(rng, 0.5, 2.0),
            "i_dt_a": 0.5,
        }
    if name == "delay":  # AA filter + S/H 1-10 us; a PWM update late by one or two periods
        return {
            "sample_delay_s": _lu(rng, 1e-6, 1e-5),
            "pwm_delay_periods": int(rng.integers(1, 3)),
        }
    if name == "encoder":  # mounting error 0.1-1.5 deg mechanical x p = 0.4-6 deg electrical
        return {"lines": 2500, "offset_e_rad": _sign(rng) * _lu(rng, 0.007, 0.1)}
    if name == "sensor_offset":  # residual offsets 0.02-0.3 % of +-50 A
        return {
            "i_a_a": _sign(rng) * _lu(rng, 0.02, 0.3),
            "i_b_a": _sign(rng) * _lu(rng, 0.02, 0.3),
            "i_c_a": 0.0,
        }
    if name == "sensor_gain":  # Hall transducer gain tolerance 0.5-5 %
        return {
            "i_a_gain": 1.0,
            "i_b_gain": 1.0 + _sign(rng) * _lu(rng, 0.005, 0.05),
            "i_c_gain": 1.0,
        }
    if name == "thermal":  # a warm machine: winding +10..+100 K, magnet +5..+60 K
        return {"temp_winding_c": 25.0 + _lu(rng, 10, 100), "temp_magnet_c": 25.0 + _lu(rng, 5, 60)}
    if name == "saturation":  # paper A's map (docs/rigs.md)
        return {"map": "MAP"}
    if name == "flux_harmonics":  # distributed-winding IPMSM: 5th 0.5-5 %, 7th 0.3-3 %
        return {"emf5_rel": _lu(rng, 0.005, 0.05), "emf7_rel": _lu(rng, 0.003, 0.03)}
    if name == "dc_link":  # 0.1-1 ohm source, 0.3-2 mF
        return {
            "r_source_ohm": _lu(rng, 0.1, 1.0),
            "c_dc_f": _lu(rng, 3e-4, 2e-3),
            "rectifier": True,
            "grid_hz": 50.0,
        }
    if name == "iron_loss":  # 0.3-3 % of 3 kW at rated speed
        return {"r_fe_ohm": _lu(rng, 100.0, 1000.0)}
    if name == "friction":  # bench drag 0.02-0.3 N m
        return {"t_coulomb_nm": _lu(rng, 0.02, 0.3), "b_visc_nms": _lu(rng, 1e-4, 1e-3)}
    if name == "cogging":  # 0.3-3 % of 18 N m
        return {
            "amplitude_nm": _lu(rng, 0.05, 0.5),
            "periods_per_rev": int(rng.choice([24, 72])),
            "phase_rad": float(rng.uniform(-np.pi, np.pi)),
        }
    raise KeyError(name)


LIBRARY = (
    "dead_time",
    "delay",
    "encoder",
    "sensor_offset",
    "sensor_gain",
    "saturation",
    "thermal",
    "flux_harmonics",
    "dc_link",
    "iron_loss",
    "friction",
    "cogging",
)


def true_primary(name: str, p: dict) -> float | None:
    """The quantity the diagnoser quotes as the effect's magnitude (pmsm_hil.gap.effects)."""
    if name == "dead_time":
        return p["dead_time_s"]
    if name == "delay":
        return p["sample_delay_s"] + p["pwm_delay_periods"] * TS_S
    if name == "encoder":
        return p["offset_e_rad"]
    if name == "sensor_offset":
        a, b = p["i_a_a"], p["i_b_a"]
        return float(np.hypot(a, (a + 2 * b) / np.sqrt(3.0)))
    if name == "sensor_gain":
        return p["i_b_gain"]
    if name == "thermal":
        return p["temp_winding_c"] - 25.0
    if name == "flux_harmonics":
        return p["emf5_rel"]
    if name == "iron_loss":
        return p["r_fe_ohm"]
    if name == "friction":
        return p["t_coulomb_nm"]
    if name == "cogging":
        return p["amplitude_nm"]
    return None


def draw_profile(rng: np.random.Generator) -> list[dict]:
    """2 s: six segments; speeds log-uniform over 100-1500 r/min with random directions, always one
    below 200 and one above 1000 r/min; random loads; i_d excitation in half of them."""
    mags = [_lu(rng, 100, 200), _lu(rng, 1000, 1450)] + [_lu(rng, 100, 1450) for _ in range(4)]
    rng.shuffle(mags)
    segs = []
    for j, v in enumerate(mags):
        s = _sign(rng)
        seg = {
            "name": f"p{j}",
            "duration_s": 1.0 / 3.0,
            "speed_rpm": round(s * v, 1),
            "ramp_rpm_s": 20000,
            "load_nm": round(s * float(rng.uniform(0, 7)), 2),
        }
        if rng.random() < 0.5:
            seg.update({"inject_a": 3.0, "inject_hz": 20})
        segs.append(seg)
    return segs


def draw_trial(rng: np.random.Generator) -> dict:
    """kind: none, one, two, or outside (a plant departure not in the library: inductances off)."""
    kind = str(rng.choice(["none", "one", "one", "one", "two", "outside"]))
    names = []
    if kind == "one":
        names = [str(rng.choice(LIBRARY))]
    elif kind == "two":
        names = [str(x) for x in rng.choice(LIBRARY, size=2, replace=False)]
    effects = {n: draw_effect(rng, n) for n in names}
    out = {
        "kind": kind,
        "effects": effects,
        "profile": draw_profile(rng),
        "profile_holdout": draw_profile(rng),
        "seed": int(rng.integers(1, 2**31 - 1)),
    }
    if kind == "outside":
        out["plant_l_scale"] = float(rng.uniform(1.08, 1.25)) ** _sign(
            rng
        )  # the plant's L_d and L_q
    return out
