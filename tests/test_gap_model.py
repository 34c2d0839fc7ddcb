"""The probe's plant model: the saturation's incremental inductance matrix stays positive definite
(pmsm_hil/gap/model.py, docs/gap.md "Which")."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.gap import model
from pmsm_hil.gap.model import L_FLOOR, MotorModel, PlantTerms, _deriv, _floored, _flux

# the SEW CM3C80S's motor file, as the nominal model
SEW = MotorModel(0.4, 2.75e-3, 3.36e-3, 0.0922, 4, 6e-4, 2e-4, 0.0, 14.0, 60.0)
# a saturation fitted on a SEW record before the floor (k_d, i_sd, k_q, i_sq, k_x, k_c): its cross
# term turns the matrix indefinite beyond about 14 A, where the record's currents went
SEW_FIT = (0.33335, 2.681, 0.60340, 2.0004, 0.52416, 0.014721)


def _eigs(a, b, c) -> np.ndarray:
    """(n, 2) ascending eigenvalues of the symmetric matrices [[a, b], [b, c]] (numpy's own
    solver, not the model's formula)."""
    m = np.stack([np.stack([a, b], -1), np.stack([b, c], -1)], -2)
    return np.linalg.eigvalsh(m)


def _min_eig(a, b, c):
    return _eigs(*np.broadcast_arrays(*np.atleast_1d(a, b, c)))[..., 0]


def _max_eig(a, b, c):
    return _eigs(*np.broadcast_arrays(*np.atleast_1d(a, b, c)))[..., 1]


inductance = st.floats(1e-4, 1e-2)


@settings(max_examples=300, deadline=None)
@given(inductance, st.floats(-1e-2, 1e-2), inductance, st.floats(1e-5, 5e-3))
def test_the_floor_leaves_a_matrix_above_it_bit_for_bit(a, b, c, l_min_h):
    arrs = np.array([a]), np.array([b]), np.array([c])
    out = _floored(*arrs, l_min_h)
    lo, hi = _min_eig(a, b, c), _max_eig(a, b, c)
    if lo >= l_min_h:
        assert all(np.array_equal(x, y) for x, y in zip(out, arrs, strict=True))
        return
    # each eigenvalue raised to the floor where it is below, kept where it is above
    tol = 1e-9 * max(a, c, abs(b), l_min_h)
    assert abs(_min_eig(*out)[0] - min(max(lo, l_min_h), max(hi, l_min_h))) <= tol
    assert abs(_max_eig(*out)[0] - max(hi, l_min_h)) <= tol
    if hi > lo:  # the eigenvectors kept: M and its floored form commute
        m = np.array([[a, b], [b, c]])
        f = np.array([[out[0][0], out[1][0]], [out[1][0], out[2][0]]])
        assert np.allclose(m @ f, f @ m, rtol=0, atol=1e-9 * max(a, c, abs(b), l_min_h) ** 2)


def test_a_mixed_batch_changes_only_the_matrices_under_the_floor():
    a = np.array([3e-3, 1e-3, 2e-3])
    b = np.array([0.0, 1.2e-3, 0.0])
    c = np.array([3e-3, 1.5e-3, 2e-3])
    l_min_h = 2.75e-4
    out = _floored(a, b, c, l_min_h)
    before = _min_eig(a, b, c)
    assert before[0] > l_min_h and before[1] < l_min_h and before[2] > l_min_h
    for x, y in zip(out, (a, b, c), strict=True):
        assert x[0] == y[0] and x[2] == y[2]  # untouched, bit for bit
    assert np.isclose(_min_eig(*out)[1], l_min_h, rtol=1e-9)


def test_a_fitted_cross_saturation_cannot_make_the_prediction_diverge():
    """On a grid over the SEW motor's currents, beyond i_max, the fitted model's incremental
    matrix is indefinite in places; with the floor, its smallest eigenvalue is at least the floor
    everywhere, and the current's rate is bounded by the voltage over that floor."""
    g = np.stack(np.meshgrid(np.linspace(-8, 6, 57), np.linspace(-18, 18, 145)), -1).reshape(-1, 2)
    pt = PlantTerms(sat=SEW_FIT)
    # the matrix as the fitted co-energy gives it, without the floor
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(model, "L_FLOOR", -np.inf)
        _, raw = _flux(SEW, g, pt, SEW.psi_f_wb)
    l_min_h = L_FLOOR * min(SEW.l_d_h, SEW.l_q_h)
    assert (_min_eig(*raw) < 0).any()  # the case the floor is for
    _, mat = _flux(SEW, g, pt, SEW.psi_f_wb)
    assert (_min_eig(*mat) >= l_min_h * (1 - 1e-9)).all()
    u = np.tile([SEW.v_dc_v / np.sqrt(3), 0.0], (len(g), 1))
    omega = np.full(len(g), 4 * 2 * np.pi * 600 / 60)
    rate = _deriv(SEW, g, u, omega, pt, SEW.r_s_ohm, SEW.psi_f_wb)
    (psi_d, psi_q), _ = _flux(SEW, g, pt, SEW.psi_f_wb)
    v = np.hypot(
        u[:, 0] - SEW.r_s_ohm * g[:, 0] + omega * psi_q,
        u[:, 1] - SEW.r_s_ohm * g[:, 1] - omega * psi_d,
    )
    assert np.isfinite(rate).all()
    assert (np.hypot(rate[:, 0], rate[:, 1]) <= v / l_min_h * (1 + 1e-9)).all()
