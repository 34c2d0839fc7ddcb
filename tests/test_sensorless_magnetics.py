"""What the sensorless estimator takes from a motor's flux map (pmsm_hil/profiles/magnetics.py,
docs/sensorless.md), the motor file's sensorless fields, and the emulator's magnetics: a motor's
own map makes the plant saturate on a rig without the saturation effect."""

from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.profiles import ProfileError
from pmsm_hil.profiles.fluxmap import FluxMap, load_flux_map
from pmsm_hil.profiles.magnetics import (
    ASYM_PHYSICS_DEFAULT,
    TABLE_MAX_NODES,
    gamma_at,
    gamma_table,
    polarity_signature,
)
from pmsm_hil.profiles.motor import load_motor
from pmsm_hil.profiles.rig import load_rig
from pmsm_hil.profiles.shipped import shipped_file as shipped_path
from pmsm_hil.sensorless_design import estimator_frames

PAPER_A_MAP = "maps/paper-a-ipmsm.csv"


def _grid(psi_d, psi_q, h=1.0, n=21):
    i = (np.arange(n) - n // 2) * h
    idg, iqg = np.meshgrid(i, i)
    return FluxMap(i, i, psi_d(idg, iqg), psi_q(idg, iqg), np.ones((n, n), bool))


def test_linear_map_gives_the_nominal_gamma_and_no_signature():
    fm = _grid(lambda d, q: 0.18 + 5e-3 * d, lambda d, q: 12e-3 * q)
    t = gamma_table(fm, -8.0, 8.0)
    g = gamma_at(t, -2.3, 4.1)
    assert g == pytest.approx([200.0, 1 / 12e-3, 0.0, 0.0], abs=1e-6)
    assert polarity_signature(fm, 5.0) == pytest.approx(0.0, abs=1e-9)


def test_positive_d_saturation_gives_a_positive_signature():
    fm = _grid(
        lambda d, q: 0.18 + np.where(d > 0, 40e-3 * np.tanh(d / 8.0), 5e-3 * d),
        lambda d, q: 12e-3 * q,
    )
    assert polarity_signature(fm, 5.0) > 0.1
    # the physics default (no map) has the same sign
    assert polarity_signature(None, 5.0) == ASYM_PHYSICS_DEFAULT > 0


def test_cross_saturation_appears_as_gamma_dq():
    # psi_d = 0.18 + L_d i_d - k i_q^2 / 2, psi_q = L_q i_q - k i_d i_q: conservative coupling
    k = 2e-4
    fm = _grid(lambda d, q: 0.18 + 5e-3 * d - 0.5 * k * q * q, lambda d, q: 12e-3 * q - k * d * q)
    t = gamma_table(fm, -8.0, 8.0)
    g = gamma_at(t, 0.0, 6.0)
    l_inc = np.array([[5e-3, -k * 6.0], [-k * 6.0, 12e-3]])
    assert g == pytest.approx(np.linalg.inv(l_inc).ravel()[[0, 3, 1, 2]], rel=1e-6)
    assert g[2] > 0 and g[2] == pytest.approx(g[3])


def test_paper_a_map_table_fits_the_firmware_and_its_signature_is_negative():
    fm = load_flux_map(shipped_path(PAPER_A_MAP))
    t = gamma_table(fm, -5.97, 15.0)
    nd, nq = t.shape
    assert nd * nq <= TABLE_MAX_NODES
    assert t.i_d_a[0] <= -5.97 - 4.0 and t.i_d_a[-1] >= 0.0
    assert t.i_q_a[0] <= -15.0 and t.i_q_a[-1] >= 15.0
    # near zero current: the map's small-signal slopes (about 5.6 and 12.5 mH)
    g0 = gamma_at(t, 0.0, 0.0)
    assert 1 / g0[0] == pytest.approx(5.6e-3, rel=0.05)
    assert 1 / g0[1] == pytest.approx(12.5e-3, rel=0.05)
    # the measured side (i_d < 0) saturates, the extrapolated side does not: negative signature
    assert polarity_signature(fm, 5.0) < -0.1


def test_motor_hybrid_band_must_be_ordered(tmp_path):
    text = Path(shipped_path("motors/paper-a-ipmsm.yaml")).read_text()
    p = tmp_path / "m.yaml"
    p.write_text(text + "hybrid_pll_on_rpm: 300\nhybrid_mras_on_rpm: 200\n")
    with pytest.raises(ProfileError) as ei:
        load_motor(p)
    msg = str(ei.value)
    assert "hybrid_mras_on_rpm" in msg and "200" in msg and "m.yaml:" in msg


def test_motor_ripple_pll_excitation_is_bounded_and_defaults_to_a_tenth_of_i_max(tmp_path):
    text = Path(shipped_path("motors/paper-a-ipmsm.yaml")).read_text()
    p = tmp_path / "m.yaml"
    p.write_text(text + "ripple_pll_excite_a: 9\n")  # i_max_a 15: at most 7.5
    with pytest.raises(ProfileError) as ei:
        load_motor(p)
    msg = str(ei.value)
    assert "ripple_pll_excite_a" in msg and "9" in msg and "i_max_a" in msg and "m.yaml:" in msg
    p.write_text(text)
    assert estimator_frames(load_motor(p))[0]["pll_excite_a"] == pytest.approx(1.5)
    p.write_text(text + "ripple_pll_excite_a: 0\n")
    assert estimator_frames(load_motor(p))[0]["pll_excite_a"] == 0.0


def test_motor_flux_map_that_cannot_be_read_is_refused(tmp_path):
    text = Path(shipped_path("motors/paper-a-ipmsm.yaml")).read_text()
    p = tmp_path / "m.yaml"
    p.write_text(text + "flux_map: missing.csv\n")
    with pytest.raises(ProfileError) as ei:
        load_motor(p)
    assert "flux_map" in str(ei.value) and "missing.csv" in str(ei.value)


def test_emulator_plant_takes_the_motors_map_when_the_rig_has_none():
    rig = load_rig(shipped_path("rigs/default.yaml"))
    measured = load_motor(shipped_path("motors/paper-a-ipmsm-measured.yaml"))
    plain = load_motor(shipped_path("motors/paper-a-ipmsm.yaml"))
    s = emulator_settings(measured, rig)
    assert s["sat_nd"] == 18 and s["sat_nq"] == 33
    assert emulator_settings(plain, rig)["sat_nd"] == 0
