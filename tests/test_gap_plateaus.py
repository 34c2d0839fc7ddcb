"""The settled-plateau view of the gap diagnosis (pmsm_hil.gap.plateaus): on `diagnose.yaml`
records it finds an encoder offset, an iron loss and warm windings that the one-step residual
cannot select, with their sizes, and nothing on a rig without them; the torque balance's viscous
friction gives up the iron loss's drag."""

from __future__ import annotations

import numpy as np
import pytest
from gap_records import record_rig

from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.plateaus import (
    BOOT,
    find_plateaus,
    less_iron_drag,
    plateau_bootstrap,
    plateau_view,
)
from pmsm_hil.gap.probe import Probe
from pmsm_hil.gap.record import load_control_record
from pmsm_hil.profiles import load_motor
from pmsm_hil.profiles.shipped import resolve

WARM = {
    "temp_winding_c": 60.0,
    "temp_magnet_c": 45.0,
    "temp_ref_c": 25.0,
    "alpha_r_per_k": 0.00393,
    "alpha_psi_per_k": -0.001,
}


def _record(tmp, name, effects, seed):
    return load_control_record(record_rig(tmp, name, effects, resolve("diagnose", "profile"), seed))


@pytest.fixture(scope="module")
def motor():
    return MotorModel.from_motor(load_motor(resolve("paper-a-ipmsm", "motor")))


def test_the_three_steady_effects_are_found_with_their_sizes(tmp_path, motor):
    rec = _record(
        tmp_path,
        "steady",
        {"encoder": {"offset_e_rad": 0.02}, "iron_loss": {"r_fe_ohm": 300.0}, "thermal": WARM},
        seed=5,
    )
    probe = Probe(rec, motor)
    assert len(find_plateaus(rec, probe.omega)) >= 10
    entries, summary = plateau_view(probe, motor, [], exclude=[])
    by = {e["name"]: e for e in entries}
    assert summary["selected"] == ["iron_loss", "encoder", "thermal"], summary
    assert by["encoder"]["magnitude"] == pytest.approx(0.02, abs=0.004)
    assert by["iron_loss"]["parameters"]["r_fe_ohm"] == pytest.approx(300.0, rel=0.35)
    assert by["thermal"]["parameters"]["temp_winding_c"] == pytest.approx(60.0, abs=10.0)
    for e in entries:  # each interval holds its own magnitude
        lo, hi = e["interval"]
        assert lo <= e["magnitude"] <= hi
    assert summary["rms_after_v"][0] < 0.5 * summary["rms_before_v"][0]


def test_nothing_is_taken_on_a_rig_without_them(tmp_path, motor):
    rec = _record(tmp_path, "null", {}, seed=6)
    entries, summary = plateau_view(Probe(rec, motor), motor, [], exclude=[])
    assert summary["selected"] == [] and not any(e["selected"] for e in entries), summary


def test_selected_effects_are_not_candidates_again(tmp_path, motor):
    rec = _record(tmp_path, "enc", {"encoder": {"offset_e_rad": 0.02}}, seed=7)
    entries, _ = plateau_view(Probe(rec, motor), motor, [], exclude=["encoder", "thermal"])
    assert {e["name"] for e in entries} == {"iron_loss"}


def test_the_iron_loss_drag_leaves_the_viscous_friction(motor):
    effects = [
        {"name": "iron_loss", "selected": True, "parameters": {"r_fe_ohm": 300.0}},
        {
            "name": "friction",
            "selected": True,
            "parameters": {"t_coulomb_nm": 0.05, "b_visc_nms": 0.003},
            "evidence": "torque balance",
        },
    ]
    less_iron_drag(effects, motor)
    drag = 1.5 * motor.pole_pairs**2 * motor.psi_f_wb**2 / 300.0
    assert effects[1]["parameters"]["b_visc_nms"] == pytest.approx(0.003 - drag)
    assert f"{drag:.3g}" in effects[1]["evidence"]
    effects[1]["parameters"]["b_visc_nms"] = 0.1 * drag  # never below zero
    less_iron_drag(effects, motor)
    assert effects[1]["parameters"]["b_visc_nms"] == 0.0
    unsel = [dict(effects[0], selected=False), dict(effects[1], parameters={"b_visc_nms": 0.003})]
    less_iron_drag(unsel, motor)  # no iron loss selected: the friction stays
    assert unsel[1]["parameters"]["b_visc_nms"] == 0.003
    assert np.isfinite(drag)


def _coverage(rng, trials: int, scale) -> tuple[float, float]:
    """Linear fits of two parameters to 14 plateaus' d and q means whose misfit is each plateau's
    own (``scale``: its size from the plateau's Jacobian), truth 0: how often the bootstrap's 95 %
    interval holds it, and how often the wider of it and the fit's own (covariance) interval."""
    n, k = 14, 2
    lo, hi = np.full(k, -10.0), np.full(k, 10.0)
    boot_in = union_in = 0
    for _ in range(trials):
        jac = rng.normal(size=(n, 2, k))
        own = rng.normal(size=(n, 1)) * scale(jac)  # on d and q alike
        y = (own + 0.05 * rng.normal(size=(n, 2))).ravel()
        j2 = jac.reshape(2 * n, k)
        z = np.linalg.lstsq(j2, y, rcond=None)[0]
        f = j2 @ z - y
        a, b = np.percentile(plateau_bootstrap(j2, f, z, lo, hi)[:, 0], [2.5, 97.5])
        se = np.sqrt(np.linalg.inv(j2.T @ j2)[0, 0] * (f @ f) / (2 * n - k))
        boot_in += a <= 0.0 <= b
        union_in += min(a, z[0] - 1.96 * se) <= 0.0 <= max(b, z[0] + 1.96 * se)
    return boot_in / trials, union_in / trials


def test_the_plateau_bootstrap_covers_a_linear_fit_at_its_level():
    """Resampling the plateaus (one Gauss-Newton step per resample) gives 95 % intervals that hold
    the truth near their level when each plateau's misfit is its own, also when it grows with the
    plateau's weight in the fit (the loaded plateaus at speed carry the saturation model's error),
    where the residuals' scatter alone understates it; plateau_view quotes the wider of the two. A
    perfect fit has no spread; the range holds."""
    rng = np.random.default_rng(13)
    boot, union = _coverage(rng, 200, lambda jac: 0.3)
    assert 0.85 <= boot <= 0.99 and 0.9 <= union <= 0.99, (boot, union)
    lev = lambda jac: 0.1 * np.sum(jac**2, axis=(1, 2))[:, None]  # noqa: E731
    boot, union = _coverage(rng, 200, lev)
    assert 0.85 <= boot <= 0.99 and 0.9 <= union <= 0.99, (boot, union)
    j2 = rng.normal(size=(28, 2))
    lo, hi, z = np.full(2, -10.0), np.full(2, 10.0), np.array([0.5, -0.2])
    same = plateau_bootstrap(j2, np.zeros(28), z, lo, hi)
    assert same.shape == (BOOT, 2) and np.allclose(same, z)
    far = plateau_bootstrap(j2, 100.0 * rng.normal(size=28), z, lo, hi)
    assert np.all(far >= lo) and np.all(far <= hi) and np.ptp(far[:, 0]) > 1.0
