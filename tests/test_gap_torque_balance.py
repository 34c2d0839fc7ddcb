"""The torque-balance view of the gap diagnosis (pmsm_hil/gap/torque_balance.py, docs/gap.md):
friction, cogging and current-sensor offsets on emulator records with known (hidden to the
diagnoser) rig effects, and nothing on the ideal plant."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gap_records import record_rig

from pmsm_hil.gap.diagnose import diagnose
from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.record import load_record
from pmsm_hil.gap.torque_balance import FRIC, NUIS, OFFS, SLOW, balance_windows, ols
from pmsm_hil.gap.views import view_effects
from pmsm_hil.profiles import load_motor

ROOT = Path(__file__).resolve().parents[1]
MOTOR = str(ROOT / "profiles/motors/paper-a-ipmsm.yaml")
PROFILE = ROOT / "tests/data/gap-mech.yaml"


def _record(tmp, name, effects, seed=5):
    return load_record(record_rig(tmp, name, effects, PROFILE, seed))


@pytest.fixture(scope="module")
def recs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("gapmech")
    return {
        "null": _record(tmp, "null", {}),
        "friction": _record(tmp, "fric", {"friction": {"t_coulomb_nm": 0.12, "b_visc_nms": 8e-4}}),
        "cogging": _record(
            tmp, "cog", {"cogging": {"amplitude_nm": 0.2, "periods_per_rev": 24, "phase_rad": 0.7}}
        ),
        "offset": _record(
            tmp, "off", {"sensor_offset": {"i_a_a": 0.12, "i_b_a": -0.06, "i_c_a": 0.0}}
        ),
    }


@pytest.fixture(scope="module")
def motor():
    return MotorModel.from_motor(load_motor(MOTOR))


def _views(rec, motor):
    return {e["name"]: e for e in view_effects(rec, motor)}


def test_ideal_plant_has_no_coulomb_term(recs, motor):
    # the recorded speed is the encoder observer's, which lags during the ramps; the balance uses a
    # zero-phase speed from the angle, so no spurious Coulomb or torque-constant term is left
    w = balance_windows(recs["null"], motor, *SLOW)
    b, _cov = ols(w, NUIS + OFFS + FRIC)
    assert abs(b[-2]) < 0.01  # N m
    assert abs(b[1]) < 0.005  # N m per A
    v = _views(recs["null"], motor)
    assert not any(v[n]["selected"] for n in ("friction", "cogging", "sensor_offset"))


def test_the_observer_speed_would_show_a_spurious_coulomb_term(recs, motor):
    # the cause of the bias that the zero-phase speed removes: the recorded speed is the encoder
    # observer's, which lags by about 2 zeta / bw during the ramps
    w = balance_windows(recs["null"], motor, *SLOW, recorded_speed=True)
    b, _ = ols(w, NUIS + OFFS + FRIC)
    assert b[-2] < -0.05  # N m


def test_friction_recovered_with_its_size(recs, motor):
    e = _views(recs["friction"], motor)["friction"]
    assert e["selected"]
    assert e["magnitude"] == pytest.approx(0.12, abs=0.015)
    assert e["interval"][0] <= 0.12 <= e["interval"][1] or abs(e["magnitude"] - 0.12) < 0.005
    assert e["parameters"]["b_visc_nms"] == pytest.approx(8e-4, abs=3e-4)


def test_cogging_recovered_with_its_order_and_size(recs, motor):
    e = _views(recs["cogging"], motor)["cogging"]
    assert e["selected"]
    assert e["parameters"]["periods_per_rev"] == 24
    assert e["magnitude"] == pytest.approx(0.2, rel=0.15)
    assert e["parameters"]["phase_rad"] == pytest.approx(0.7, abs=0.2)


def test_sensor_offset_named_right_not_cogging(recs, motor):
    res = diagnose(recs["offset"], motor)
    names = [e["name"] for e in res["effects"] if e["selected"]]
    assert names == ["sensor_offset"], res["verdict"]
    e = next(e for e in res["effects"] if e["name"] == "sensor_offset")
    true_norm = np.hypot(0.12, (0.12 + 2 * -0.06) / np.sqrt(3.0))  # |offset| in alpha-beta
    assert e["magnitude"] == pytest.approx(true_norm, rel=0.15)
    assert e["parameters"]["i_a_a"] == pytest.approx(0.12, abs=0.02)
    assert e["parameters"]["i_b_a"] == pytest.approx(-0.06, abs=0.02)
    assert "sensor_offset" in res["verdict"]


def test_probe_speed_follows_the_angle_so_no_resistance_bias(recs, motor):
    # the probe's EMF uses a speed consistent with the angle; with the observer's lagging speed the
    # ramps put psi_f * lag * acceleration on the q axis, read as a higher resistance
    from pmsm_hil.gap.fit import fit_effects
    from pmsm_hil.gap.probe import Probe

    rec = recs["null"]
    p = Probe(rec, motor)
    sel = np.arange(len(p.idx))[::2]
    r_scale = fit_effects(p, ["parameters"], sel).x["parameters"][0]
    assert abs(r_scale - 1.0) < 0.04  # what is left: the smoothing at the ramps' corners
    p.omega = rec.omega_e_rad_s  # the recorded (observer) speed
    r_lagged = fit_effects(p, ["parameters"], sel).x["parameters"][0]
    assert r_lagged > 1.08
