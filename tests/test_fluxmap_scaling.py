"""A rig's flux map on another motor: its saturation is carried over by co-energy scaling, so the
plant keeps the motor's own psi_f, L_d, L_q at small current (paper B's SPMSM on lab-typical is not
turned into paper A's IPMSM), and a map that is the motor's own is used as it is."""

from __future__ import annotations

import numpy as np
import pytest
from emu_helpers import run_inproc
from mcap.reader import make_reader

from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_motor
from pmsm_hil.profiles.fluxmap import for_motor, load_flux_map
from pmsm_hil.profiles.shipped import shipped_file


@pytest.fixture(scope="module")
def paper_a_map():
    return load_flux_map(shipped_file("maps/paper-a-ipmsm.csv"))


@pytest.mark.parametrize(
    "target", [(0.175, 8.5e-3, 8.5e-3), (0.09, 2.0e-3, 6.0e-3), (0.3, 20e-3, 25e-3)]
)
def test_scaled_map_has_the_motors_small_current_values(paper_a_map, target):
    fm, info = paper_a_map.scaled_to(*target)
    assert fm.small_current() == pytest.approx(target, rel=1e-9)
    assert info["s_d"] > 0 and info["s_q"] > 0 and info["c"] > 0


def _cross(fm):
    """d psi_d / d i_q and d psi_q / d i_d on the grid (central differences, interior)."""
    dpd_diq = np.gradient(fm.psi_d_wb, fm.i_q_a, axis=0)[1:-1, 1:-1]
    dpq_did = np.gradient(fm.psi_q_wb, fm.i_d_a, axis=1)[1:-1, 1:-1]
    return dpd_diq, dpq_did


def test_scaling_keeps_the_map_reciprocal(paper_a_map):
    a, b = _cross(paper_a_map)
    fm, info = paper_a_map.scaled_to(0.175, 8.5e-3, 8.5e-3)
    c, d = _cross(fm)
    # each cross derivative scales by c s_d s_q: the mismatch the map had, no more
    k = info["c"] * info["s_d"] * info["s_q"]
    assert np.allclose(c, k * a) and np.allclose(d, k * b)
    assert np.max(np.abs(c - d)) == pytest.approx(k * np.max(np.abs(a - b)), rel=1e-9)


def test_the_motors_own_map_is_used_as_it_is(paper_a_map):
    m = load_motor(shipped_file("motors/paper-a-ipmsm.yaml"))
    fm, info = for_motor(paper_a_map, m.psi_f_wb, m.l_d_h, m.l_q_h)
    assert fm is paper_a_map and info == {}
    m = load_motor(shipped_file("motors/paper-b-spmsm.yaml"))
    fm, info = for_motor(paper_a_map, m.psi_f_wb, m.l_d_h, m.l_q_h)
    assert fm is not paper_a_map and info["s_d"] > 1.2


def test_paper_b_on_lab_typical_runs_its_own_motor_saturating(tmp_path):
    out = tmp_path / "pb-lab.mcap"
    run_inproc(
        shipped_file("paper-b.yaml"),
        out,
        seed=3,
        rig=shipped_file("rigs/lab-typical.yaml"),
        stop_after_s=0.05,
    )
    tr = read_log(str(out)).topic("/sim/truth")
    # at rest, no current: about paper B's 8.5 mH (the slope at the origin itself, a few %
    # from the fit over the nodes near it), not paper A's 5 / 12 mH
    assert float(tr["l_d_h"][0]) == pytest.approx(8.5e-3, rel=0.06)
    assert float(tr["l_q_h"][0]) == pytest.approx(8.5e-3, rel=0.06)
    with open(out, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    rig = meta["rig_effects"]
    assert "saturation" in rig["effects"].split(",")
    assert float(rig["saturation.scaled_s_d"]) > 1.2


_MAP = "# measured\ni_d_a,i_q_a,psi_d_wb,psi_q_wb\n" + "".join(
    f"{d},{q},{0.18 + 0.005 * d:.4f},{0.012 * q:.4f}\n" for q in (-1, 0, 1) for d in (-1, 0)
)


@pytest.mark.parametrize(
    "edit,needle",
    [  # the file's own line numbers (the comment line counted), the column and the value
        (
            lambda t: t.replace("0.1750,-0.0120", "0.1750,nan"),
            "line 3: psi_q_wb = 'nan' is not finite",
        ),
        (
            lambda t: t.replace("0.1800,0.0000", "0.1800,x"),
            "line 6: psi_q_wb = 'x' is not a number",
        ),
        (lambda t: t.replace("0,1,0.1800", "0,1,"), "line 8: psi_d_wb = '' is not a number"),
        (
            lambda t: t + "-1,0,0.1750,0.0000\n",
            "line 9: the node i_d_a = -1, i_q_a = 0 is given twice (first on line 5)",
        ),
        (lambda t: t.replace("psi_q_wb", "psi_q"), "line 2: missing column(s) psi_q_wb"),
        # a flux that does not rise with its own current: the plant could not find the currents
        (
            lambda t: t.replace("0,1,0.1800,0.0120", "0,1,0.1800,-0.0130"),
            "psi_q_wb does not rise with i_q_a between i_q_a = 0 and 1 A at i_d_a = 0 A "
            "(0 -> -0.013 Wb; 1 such cells)",
        ),
        (
            lambda t: t.replace("-1,0,0.1750", "-1,0,0.1800"),
            "psi_d_wb does not rise with i_d_a between i_d_a = -1 and 0 A at i_q_a = 0 A",
        ),
    ],
)
def test_flux_map_errors_name_line_column_and_value(tmp_path, edit, needle):
    from pmsm_hil.profiles.fluxmap import FluxMapError

    p = tmp_path / "map.csv"
    p.write_text(_MAP)
    assert load_flux_map(str(p)).shape == (2, 3)  # the file as it is loads
    p.write_text(edit(_MAP))
    with pytest.raises(FluxMapError) as e:
        load_flux_map(str(p))
    assert needle in str(e.value)
