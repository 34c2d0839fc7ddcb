"""Commissioning a motor of one's own (a 48 V, 8-pole servo from its datasheet, tests/data) and
the mistakes made on the way (docs/commissioning.md): a motor file with the wrong pole-pair
count and a rig file that misstates the encoder's lines each stop the encoder step with the
numbers that fit; a test current too weak against friction and cogging says so and what to
change; a test current whose R levels lie in the inverter's knee is warned of."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from pmsm_hil.cli.main import main as cli_main
from pmsm_hil.commission.sequence import commission_in_process

DATA = Path(__file__).parent / "data"
MOTOR = DATA / "servo-48v.yaml"
RIG = DATA / "servo-48v-rig.yaml"


def _variant(tmp_path: Path, src: Path, name: str, change) -> Path:
    data = yaml.safe_load(src.read_text())
    change(data)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def _number_after(text: str, words: str) -> float:
    m = re.search(re.escape(words) + r" ([0-9.e+]+)", text)
    assert m, text
    return float(m.group(1))


def test_poles_taken_for_pole_pairs_stop_the_encoder_step_with_the_count_that_fits(tmp_path):
    """8 poles written as pole_pairs 8 (and psi_f from the datasheet's Ke with that p: half);
    the rig's motor_deviation makes the emulated motor the real one (4 pole pairs)."""

    def wrong_p(m):
        m["pole_pairs"], m["psi_f_wb"] = 8, m["psi_f_wb"] / 2

    def real_motor(r):
        r["effects"]["motor_deviation"] = {"pole_pairs": 4, "psi_f_factor": 2.0}

    motor = _variant(tmp_path, MOTOR, "wrong-p.yaml", wrong_p)
    rig = _variant(tmp_path, RIG, "real-p.yaml", real_motor)
    _p, res = commission_in_process(motor, rig, 1, tmp_path / "c.mcap", tmp_path / "out.yaml")
    assert (res.failed_step, res.failed_why) == ("encoder", "pole_pairs"), res.failure
    # one field turn measured with the rotor settled at both ends (0.97 turns, read as 4.12 pole
    # pairs, while the check came as the move ended)
    assert _number_after(res.failure, "the motor has pole_pairs") == pytest.approx(4, abs=0.05)
    assert "not the motor file's 8" in res.failure
    assert not (tmp_path / "out.yaml").exists()


def test_a_rig_file_that_misstates_the_encoder_lines_is_told_the_lines_that_fit(tmp_path):
    def told_2500(r):
        r["effects"]["encoder"]["lines_told"] = 2500  # the encoder has 1000

    rig = _variant(tmp_path, RIG, "told.yaml", told_2500)
    _p, res = commission_in_process(MOTOR, rig, 1, tmp_path / "c.mcap", tmp_path / "out.yaml")
    assert (res.failed_step, res.failed_why) == ("encoder", "pole_pairs"), res.failure
    assert _number_after(res.failure, "the encoder has") == pytest.approx(1000, rel=0.005)
    assert "not the rig's encoder.lines 2500" in res.failure


def test_a_test_current_too_weak_against_friction_and_cogging_says_so(tmp_path):
    """1 A gives 0.11 N m against the rig's 0.02 N m cogging and 0.01 N m friction: the rotor
    stays where they hold it and the offset samples scatter."""

    def low_limit(m):
        m.update(i_max_a=1.0, i_trip_a=2.0, torque_max_nm=0.1)

    motor = _variant(tmp_path, MOTOR, "low-i.yaml", low_limit)
    _p, res = commission_in_process(motor, RIG, 1, tmp_path / "c.mcap")
    assert (res.failed_step, res.failed_why) == ("encoder", "not_repeatable"), res.failure
    assert _number_after(res.failure, "scatter by") > 2.9
    assert "a larger --i-test" in res.failure


@pytest.mark.parametrize(("i_test", "warned"), [("2", True), ("4", False)])
def test_r_levels_in_the_inverters_knee_are_warned_of(tmp_path, capsys, i_test, warned):
    """At 2 A the R step's lower level (1.4 A) is under 6 i_dt (about 2.4 A): R comes out about
    2 % high, and the command says so; at 4 A both levels are past the knee."""
    out = tmp_path / "c.yaml"
    args = ["commission", "--motor", str(MOTOR), "--rig", str(RIG), "--i-test", i_test]
    assert cli_main([*args, "--log", str(tmp_path / "c.mcap"), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert ("warning: R was measured at 1.4 A and 2 A" in err) == warned, err
    if warned:
        assert _number_after(err, "commission with --i-test") > 2.0
    assert out.is_file()
