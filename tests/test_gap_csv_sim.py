"""The gap diagnosis through its CSV interface (docs/gap.md, "CSV import") on data from an independent toy simulator
(tests/gap_toy_sim.py: PI current control, carrier PWM duties, hard-sign dead time, Euler
sub-steps): no sensor specification, so the noise floor comes from the data."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from pmsm_hil.gap.csv_import import import_csv
from pmsm_hil.gap.diagnose import diagnose
from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.record import load_record
from pmsm_hil.profiles import load_motor

ROOT = Path(__file__).resolve().parents[1]
MOTOR = ROOT / "profiles/motors/paper-a-ipmsm.yaml"
sys.path.insert(0, str(Path(__file__).parent))
from gap_toy_sim import simulate  # noqa: E402


@pytest.mark.parametrize("dead_time_s", [0.0, 2e-6])
def test_independent_simulator_csv(tmp_path, dead_time_s):
    csv = tmp_path / "toy.csv"
    simulate(csv, dead_time_s=dead_time_s, t_end=0.5, seed=3)
    import_csv(csv, MOTOR, tmp_path / "toy.mcap")
    rec = load_record(tmp_path / "toy.mcap")
    assert rec.voltage_kind == "duty" and rec.sensor_spec == {}
    res = diagnose(rec, MotorModel.from_motor(load_motor(MOTOR)))
    assert res["noise_floor_source"].startswith("estimated from the data")
    if dead_time_s == 0.0:
        assert res["selected"] == [] and res["verdict"] == "no structural gap found"
    else:
        assert res["selected"][:1] == ["dead_time"]
        e = res["effects"][0]
        assert e["magnitude"] == pytest.approx(dead_time_s, rel=0.15)
        assert e["interval"][0] <= dead_time_s <= e["interval"][1]
        assert res["closure"]["closure"] > 0.8
