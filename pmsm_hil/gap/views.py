"""Views for the effects the one-step current residual does not fit (docs/gap.md, "Which"):
dc_link from the measured DC-link voltage; friction, cogging and sensor offsets from the torque
balance (pmsm_hil.gap.torque_balance)."""

from __future__ import annotations

import numpy as np

from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.record import ControlRecord
from pmsm_hil.gap.torque_balance import torque_balance_effects

DC_RIPPLE_REL = 0.002  # DC-link voltage varying by more than 0.2 % rms: a soft link


def _dc_link(rec: ControlRecord) -> dict:
    v = rec.v_dc_v
    if rec.voltage_kind == "alphabeta" or np.all(np.isnan(v)):
        return {
            "name": "dc_link",
            "selected": False,
            "magnitude": None,
            "quantity": "v_dc_ripple_rms_v",
            "interval": None,
            "closure": None,
            "evidence": "no DC-link voltage in the data",
        }
    sd = float(np.std(v))
    # 95 % interval of the rms deviation: bootstrap over 20 ms blocks of the squared deviation
    sq = (v - np.mean(v)) ** 2
    nb = max(len(v) // max(round(0.02 / rec.ts_s), 1), 2)
    blocks = np.array([p.mean() for p in np.array_split(sq, nb)])
    rng = np.random.default_rng(0)
    boot = np.sqrt(blocks[rng.integers(0, nb, size=(400, nb))].mean(1))
    ci = [float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))]
    rel = sd / max(float(np.mean(v)), 1e-9)
    return {
        "name": "dc_link",
        "selected": bool(rel > DC_RIPPLE_REL),
        "magnitude": sd,
        "quantity": "v_dc_ripple_rms_v",
        "interval": ci,
        "closure": None,
        "evidence": f"measured v_dc varies {rel:.2%} rms (threshold {DC_RIPPLE_REL:.1%}); the probe uses the "
        f"measured v_dc, so the current residual does not carry it",
    }


def view_effects(rec: ControlRecord, m: MotorModel) -> list[dict]:
    return [_dc_link(rec), *torque_balance_effects(rec, m)]
