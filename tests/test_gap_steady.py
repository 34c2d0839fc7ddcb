"""`pmsm-hil gap` on imported steady-state dq data (docs/gap.md, "CSV import"): the console shows
the fitted R, Ld, Lq, psi_f with units and intervals, `--report` writes its report with the parts
that do not apply named and why, and `gap augment` writes a rig file that says why it is empty."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from pmsm_hil.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
MOTOR = str(ROOT / "profiles/motors/paper-a-ipmsm.yaml")  # R 0.9 ohm, Ld 5 mH, Lq 12 mH, 0.18 Wb
POLE_PAIRS = 4
# the "real" machine of the CSV: warm (R + 20 %), Lq 10 % below the motor file
TRUE = {"R": 1.08, "Ld": 5.0e-3, "Lq": 10.8e-3, "psi_f": 0.18}


def _steady_csv(path: Path, n: int = 40, seed: int = 0) -> None:
    """Steady operating points of TRUE's voltage equations with 0.05 V of measurement noise."""
    rng = np.random.default_rng(seed)
    rpm = rng.uniform(200, 1500, n)
    w = rpm * POLE_PAIRS * 2 * np.pi / 60
    idd, iq = rng.uniform(-5, 0, n), rng.uniform(0, 12, n)
    ud = TRUE["R"] * idd - w * TRUE["Lq"] * iq + rng.normal(0, 0.05, n)
    uq = TRUE["R"] * iq + w * (TRUE["Ld"] * idd + TRUE["psi_f"]) + rng.normal(0, 0.05, n)
    rows = ["t_s,u_d_v,u_q_v,i_d_a,i_q_a,speed_rpm"]
    rows += [
        f"{k * 0.5:.3f},{ud[k]:.6f},{uq[k]:.6f},{idd[k]:.6f},{iq[k]:.6f},{rpm[k]:.3f}"
        for k in range(n)
    ]
    path.write_text("\n".join(rows) + "\n")


@pytest.fixture
def scope(tmp_path) -> Path:
    _steady_csv(tmp_path / "scope.csv")
    out = tmp_path / "scope.mcap"
    assert main(["import", str(tmp_path / "scope.csv"), "--motor", MOTOR, "-o", str(out)]) == 0
    return out


def _printed(text: str, name: str, unit: str) -> tuple[float, float, float]:
    """(value, low, high) of `NAME value UNIT [low, high]` in the printed verdict."""
    num = r"(-?[0-9.]+(?:e[-+]?[0-9]+)?)"
    m = re.search(rf"\b{re.escape(name)} {num} {unit} \[{num}, {num}\]", text)
    assert m, f"{name} ... {unit} [lo, hi] not in: {text}"
    return float(m[1]), float(m[2]), float(m[3])


def test_console_shows_the_fitted_parameters_with_units_and_intervals(scope, capsys):
    capsys.readouterr()
    assert main(["gap", str(scope)]) == 0  # the motor from the log's attachment
    text = capsys.readouterr().out
    assert "parametric gap" in text
    for name, unit, scale, truth in (
        ("R", "ohm", 1.0, TRUE["R"]),
        ("Ld", "mH", 1e3, TRUE["Ld"]),
        ("Lq", "mH", 1e3, TRUE["Lq"]),
        ("psi_f", "Wb", 1.0, TRUE["psi_f"]),
    ):
        v, lo, hi = _printed(text, name, unit)
        assert lo < v < hi
        assert lo <= truth * scale <= hi, (name, lo, truth * scale, hi)
    # the same numbers as the JSON's
    assert main(["gap", str(scope), "--json"]) == 0
    p = json.loads(capsys.readouterr().out)["parametric_gap"]
    assert _printed(text, "R", "ohm")[0] == pytest.approx(p["r_s_ohm"], rel=1e-3)
    assert _printed(text, "Lq", "mH")[0] == pytest.approx(p["l_q_h"] * 1e3, rel=1e-3)
    lo, hi = p["interval_95"]["l_q_h"]
    assert lo <= TRUE["Lq"] <= hi and not lo <= 12e-3 <= hi  # the motor file's Lq is outside


def test_report_of_steady_data_is_written_and_names_what_does_not_apply(scope, tmp_path, capsys):
    rep = tmp_path / "gapscope"
    assert main(["gap", str(scope), "--report", str(rep)]) == 0
    assert (rep / "gap.json").exists() and (rep / "index.html").exists()
    page = (rep / "index.html").read_text()
    assert "R " in page and "Lq " in page and "mH" in page
    for part in ("effects", "residual maps", "discretisation gap", "noise floor", "fitted rig"):
        assert f"not assessed: {part} (" in page, part
    assert "no one-step residual, so no residual maps" in page
    # no plots and no rig file from data that has no effects fitted (and no `gap verify` to offer)
    assert not (rep / "residual_maps.png").exists()
    assert not (rep / "fitted-rig.yaml").exists()
    assert "gap verify" not in capsys.readouterr().out
    res = json.loads((rep / "gap.json").read_text())
    assert res["kind"] == "steady-state dq" and "effects" in res["not_assessed"]


def test_augment_of_steady_data_says_why_the_rig_is_empty(scope, tmp_path, capsys):
    out = tmp_path / "fitted-rig.yaml"
    assert main(["gap", "augment", str(scope), "-o", str(out)]) == 0
    text = out.read_text()
    assert yaml.safe_load(text)["effects"] == {}
    assert "# no effect is fitted on steady-state data" in text


def test_verify_is_offered_only_for_a_log_whose_profile_it_can_rerun(scope, data, tmp_path):
    """`gap --report` points at `gap verify`, which re-runs the log's own profile: an imported
    log has none, a `pmsm-hil run` log has it."""
    from emu_helpers import run_inproc

    from pmsm_hil.cli.gap import _reruns

    assert not _reruns(scope)
    run_log = tmp_path / "run.mcap"
    run_inproc(data / "short.yaml", run_log)
    assert _reruns(run_log)


def test_a_closure_far_outside_its_range_is_not_printed_as_a_number():
    from pmsm_hil.gap.report import closure_text

    assert [closure_text(v) for v in (0.874, 1.0, -3.0, 3.6e10, None)] == [
        "0.87",
        "1.00",
        "< -1",
        "> 10",
        "-",
    ]


def _flux_map_steady_csv(path: Path, r_s_ohm: float = 0.4) -> None:
    """Steady operating points from the shipped SEW CM3C80S map, measured as it is (its
    psi_q(0, 0) = -6 mWb artefact kept): u_d = R i_d - w psi_q(i), u_q = R i_q + w psi_d(i), at 300
    and 600 r/min (p = 4)."""
    fm = np.loadtxt(ROOT / "profiles/maps/sew-cm3c80s.csv", delimiter=",", comments="#", skiprows=4)
    rows, t = ["t_s,u_d_v,u_q_v,i_d_a,i_q_a,speed_rpm"], 0.0
    for rpm in (300.0, 600.0):
        w = rpm * 4 * 2 * np.pi / 60
        for idd, iq, pd, pq in fm:
            rows.append(
                f"{t:.1f},{r_s_ohm * idd - w * pq:.6f},{r_s_ohm * iq + w * pd:.6f},{idd},{iq},{rpm}"
            )
            t += 0.5
    path.write_text("\n".join(rows) + "\n")


def test_a_saturating_motor_is_not_reported_as_constant_inductances(tmp_path, capsys):
    """A measured flux map's steady points: the constant fit's Lq says nothing of the motor (the
    map's secant Lq falls from 2.9 mH at 4 A to 1.75 mH at 16 A); the verdict says the inductances
    depend on the current, and names psi_q(0, 0) (about -6 mWb in the data)."""
    _flux_map_steady_csv(tmp_path / "map.csv")
    out = tmp_path / "map.mcap"
    motor = str(ROOT / "profiles/motors/sew-cm3c80s.yaml")
    assert main(["import", str(tmp_path / "map.csv"), "--motor", motor, "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["gap", str(out)]) == 0
    text = capsys.readouterr().out
    assert "the inductances depend on the current (saturation)" in text
    assert "psi_q at zero current" in text
    assert main(["gap", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    dep = res["current_dependence"]
    assert "l_q_h" in dep["changed"]
    assert dep["below"]["l_q_h"] > 1.1 * dep["above"]["l_q_h"]
    assert -7e-3 < res["d_axis_emf"]["psi_q0_wb"] < -4e-3


def test_a_linear_motor_is_not_said_to_saturate(scope, capsys):
    capsys.readouterr()
    assert main(["gap", str(scope), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["current_dependence"]["changed"] == []
    assert "d_axis_emf" not in res
    assert "depend on the current" not in res["verdict"]
