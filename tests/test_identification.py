"""Online identification end to end on the in-process emulator (paper A motor, default rig with
noise and dead time): the R injection, the three estimators, the guards, the table and the CLI."""

from __future__ import annotations

import numpy as np
import pytest
from emu_helpers import run_inproc

from pmsm_hil.analysis.identification import identification_table, markdown_table, text_table
from pmsm_hil.cli.main import main as cli_main
from pmsm_hil.log.reader import read_log


@pytest.fixture(scope="module")
def ident_run(tmp_path_factory, request):
    root = request.config.rootpath
    out = tmp_path_factory.mktemp("ident") / "identify.mcap"
    profile, result = run_inproc(root / "profiles" / "paper-a-identify.yaml", out)
    return profile, result, out


def test_identify_run_completes_and_streams_every_estimator(ident_run):
    _profile, result, out = ident_run
    assert result.state == "done" and result.faults == 0
    par = read_log(out).topic("/pmsm/params")
    names = set(np.asarray(par["estimator"]).astype(str))
    assert names == {"nominal", "rls", "adaline", "nlms_adaline"}
    ev = read_log(out).topic("/pmsm/events")
    r_mohm = [int(a) for k, a in zip(ev["kind"], ev["arg"], strict=True) if k == "r_identified"]
    # the standstill injection (trapezoidal window means, residual L di/dt removed): within 2 %
    assert len(r_mohm) == 1 and abs(r_mohm[0] / 900.0 - 1.0) < 0.02, r_mohm


def test_nlms_adaline_estimates_within_bounds(ident_run):
    profile, _, out = ident_run
    drift = next(s for s in profile.segments if s.plant is not None)
    table = identification_table(out, 0.0, drift.t_start_s)
    c = {p: table.cell("nlms_adaline", p) for p in ("l_d_h", "l_q_h", "psi_f_wb", "r_s_ohm")}
    # measured figures (docs/identification.md): L_q and psi_f within 0.5 %, L_d within 1 %;
    # R is the online one (from the injection, refined from the d equation: -3.4 % on the default
    # rig, where the firmware's hard-sign dead-time model misses the rig's current-dependent band)
    assert abs(c["l_q_h"].error_rel) < 0.01
    assert abs(c["psi_f_wb"].error_rel) < 0.01
    assert abs(c["l_d_h"].error_rel) < 0.015
    assert abs(c["r_s_ohm"].error_rel) < 0.10
    assert c["l_q_h"].conv_s is not None and c["l_q_h"].conv_s < 0.5
    assert c["psi_f_wb"].conv_s is not None and c["psi_f_wb"].conv_s < 0.5
    # RLS converges too, in the same run
    assert abs(table.cell("rls", "l_q_h").error_rel) < 0.01
    assert "| L_d (mH) |" in markdown_table(table) and "nlms_adaline:" in text_table(table)


def test_predictor_fed_by_nlms_once_converged(ident_run):
    _, _, out = ident_run
    par = read_log(out).topic("/pmsm/params")
    names = np.asarray(par["estimator"]).astype(str)
    feeds = np.asarray(par["feeds_predictor"], dtype=bool)
    assert feeds[names == "nlms_adaline"].any()
    assert not feeds[names == "rls"].any() and not feeds[names == "adaline"].any()


def test_drift_step_reaches_the_plant_truth(ident_run):
    profile, _, out = ident_run
    tr = read_log(out).topic("/sim/truth")
    drift = next(s for s in profile.segments if s.plant is not None)
    before = tr["t_s"] < drift.t_start_s - 0.05
    after = tr["t_s"] > drift.t_start_s + 0.05
    assert np.allclose(tr["r_s_ohm"][after], 0.9 * 1.3, rtol=1e-3)
    assert np.allclose(tr["r_s_ohm"][before], 0.9, rtol=1e-3)
    assert np.allclose(tr["psi_f_wb"][after], 0.18 * 0.95, rtol=1e-3)


def test_guard_freezes_ld_without_d_current(tmp_path, request):
    """i_d = 0 control and no excitation: at steady state (|i_d| below the 0.5 A guard) L_d is not
    updated while psi_f and L_q are; L_d moves only in transients where |mean i_d| >= 0.5 A."""
    root = request.config.rootpath
    text = (root / "profiles" / "paper-a-identify.yaml").read_text()
    text = text.replace("current_ref: mtpa", "current_ref: id_zero").replace(
        "inject_a: 2.0", "inject_a: 0.0"
    )
    text = text.replace("motor: motors/", f"motor: {root}/profiles/motors/").replace(
        "rig: rigs/", f"rig: {root}/profiles/rigs/"
    )
    p = tmp_path / "noexc.yaml"
    p.write_text(text)
    out = tmp_path / "noexc.mcap"
    run_inproc(p, out)
    par = read_log(out).topic("/pmsm/params")
    sel = np.asarray(par["estimator"]).astype(str) == "nlms_adaline"
    t = np.asarray(par["t_s"])[sel]
    steady = (t > 1.8) & (t < 3.0)
    assert np.ptp(np.asarray(par["l_d_h"])[sel][steady]) == 0.0
    assert not np.asarray(par["excited"], dtype=bool)[sel][steady].any()
    assert np.ptp(np.asarray(par["psi_f_wb"])[sel][steady]) > 0.0
    assert abs(np.asarray(par["psi_f_wb"])[sel][steady][-1] / 0.18 - 1) < 0.01


def test_bench_identify_cli(tmp_path, capsys):
    assert cli_main(["bench", "identify", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "nlms_adaline:" in text and "paper" in text
    assert (tmp_path / "identify.png").stat().st_size > 1000
    assert "| L_q (mH) |" in (tmp_path / "identify.md").read_text()


def test_analyze_prints_identification_table(ident_run, capsys):
    _, _, out = ident_run
    assert cli_main(["analyze", str(out)]) == 0
    assert "identification (" in capsys.readouterr().out


def test_default_window_ends_where_the_estimators_stopped(ident_run):
    """Without a window the table ends at the last params message at which an estimate moved:
    the profile's last estimating segment (the drift), not the stop after it, where the plant's
    truth moves on (on a saturating rig the inductances at rest are not those identified)."""
    profile, _, out = ident_run
    table = identification_table(out)
    par = read_log(out).topic("/pmsm/params")
    stop = [s for s in profile.segments if s.estimate is False and s.t_start_s > 1.0][-1]
    assert table.t1_s < float(np.max(par["t_s"])) - 0.3  # the stop segment lasts 0.8 s
    assert abs(table.t1_s - stop.t_start_s) < 0.02, (table.t1_s, stop.t_start_s)


def test_convergence_text_says_never_or_shorter_than_one_update():
    from pmsm_hil.analysis.identification import Cell, convergence_time

    t = np.arange(0.0, 1.0, 0.01)
    truth = np.full_like(t, 12e-3)
    # within +-2 % from the first update on: 0 s, shown as shorter than one params period
    at_once = convergence_time(t, truth * 1.01, truth, 0.0)
    assert at_once == 0.0
    c = Cell("rls", "l_q_h", 12e-3, 12e-3, 0.0, 0.0, 0.0, at_once, True, step_s=0.01)
    assert c.conv_text() == "<0.010"
    # settles at 0.5 s
    est = np.where(t < 0.5, truth * 0.5, truth)
    c.conv_s = convergence_time(t, est, truth, 0.0)
    assert c.conv_text(2) == "0.50"
    # leaves the band at the end: never
    c.conv_s = convergence_time(t, np.where(t > 0.9, truth * 1.1, truth), truth, 0.0)
    assert c.conv_s is None and c.conv_text() == "never"
