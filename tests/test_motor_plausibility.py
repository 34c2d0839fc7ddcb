"""A motor file of one's own whose numbers are legal but in the wrong unit (a flux linkage 1000 x
too small, inductances in H written for mH or in uH, a resistance in mohm written as ohm, an
inertia in kg cm^2 written as kg m^2) is warned of at load, naming file, line, field and value,
where it used to run (or commission) without a word and miss its speeds; `pmsm-hil check`
validates the files without running them; a fault names the motor file's limit it tripped on."""

from __future__ import annotations

import math
import re
import textwrap
from pathlib import Path

import pytest

from pmsm_hil.cli.main import main as cli_main
from pmsm_hil.profiles import ProfileError, load_profile
from pmsm_hil.profiles.shipped import shipped, shipped_root

# A 400 W, 8-pole servo for 48 V from its datasheet: R 0.35 ohm and L_d 1.1 mH, L_q 1.6 mH per
# phase, Ke 18.5 V/krpm line-line peak (psi_f = 18.5 / (sqrt 3 x 104.72 x 4)), 15 A rms peak
# current (21.2 A), J 0.35 kg cm^2.
MOTOR = """\
name: servo400
pole_pairs: 4
r_s_ohm: 0.35
l_d_h: 0.0011
l_q_h: 0.0016
psi_f_wb: 0.025499
j_kgm2: 3.5e-5
v_dc_v: 48.0
i_max_a: 21.2
i_trip_a: 30.0
speed_max_rpm: 2500.0
speed_trip_rpm: 3000.0
torque_max_nm: 3.0
v_dc_min_v: 36.0
v_dc_max_v: 60.0
"""

# Up to 2000 r/min and back, without load: no segment that the voltage check would refuse.
PROFILE = """\
name: servo400-walk
motor: motor.yaml
rig: rig.yaml
segments:
  - {name: up, duration_s: 1.5, speed_rpm: 2000, ramp_rpm_s: 2000}
  - {name: stop, duration_s: 1.5, speed_rpm: 0, ramp_rpm_s: 2000}
"""

LINE = {k: i for i, k in enumerate((ln.split(":")[0] for ln in MOTOR.splitlines()), 1)}


def _files(tmp_path: Path, **motor_values: str) -> Path:
    lines = [
        f"{k}: {motor_values[k]}" if (k := ln.split(":")[0]) in motor_values else ln
        for ln in MOTOR.splitlines()
    ]
    (tmp_path / "motor.yaml").write_text("\n".join(lines) + "\n")
    (tmp_path / "rig.yaml").write_text("name: bench\n")
    (tmp_path / "p.yaml").write_text(PROFILE)
    return tmp_path / "p.yaml"


def test_the_datasheet_motor_loads_without_warnings(tmp_path):
    assert load_profile(_files(tmp_path)).warnings == []


@pytest.mark.parametrize(
    ("values", "field", "words"),
    [
        (
            {"psi_f_wb": "2.5499e-5", "torque_max_nm": "0.5"},
            "psi_f_wb",
            ["0.13 % of the DC link's 27.71 V", "in Wb"],
        ),
        ({"l_d_h": "1.1"}, "l_d_h", ["takes 0.841 s to drive i_max_a 21.2 A", "in H"]),
        ({"l_q_h": "1.6"}, "l_q_h", ["takes 1.22 s", "in H"]),
        ({"l_d_h": "1.1e-6"}, "l_d_h", ["under a tenth of a control period", "59.4 x i_max_a"]),
        ({"r_s_ohm": "350"}, "r_s_ohm", ["needs 7420 V to carry i_max_a 21.2 A", "in ohm"]),
    ],
)
def test_a_value_in_the_wrong_unit_is_warned_of_at_its_line(tmp_path, values, field, words):
    warnings = load_profile(_files(tmp_path, **values)).warnings
    (w,) = [w for w in warnings if f": {field} = " in w]
    value = values[field]
    assert w.startswith(f"{tmp_path / 'motor.yaml'}:{LINE[field]}: {field} = {float(value):g} ")
    for text in words:
        assert text in w, w


def test_an_inertia_in_kg_cm2_is_warned_of_at_the_ramps_it_cannot_follow(tmp_path):
    warnings = load_profile(_files(tmp_path, j_kgm2="0.35")).warnings
    assert len(warnings) == 2  # the ramp up and the ramp down
    assert warnings[0].startswith(f"{tmp_path / 'p.yaml'}:5: segments[0].ramp_rpm_s = 2000 ")
    assert "needs 73.3 N m to accelerate j_kgm2 0.35 kg m^2" in warnings[0]
    assert "torque_max_nm 3 N m" in warnings[0] and "kg cm^2" in warnings[0]


def test_the_shipped_profiles_and_motors_are_not_warned_of():
    for path in shipped("profile"):
        for motor in [None, *shipped("motor")]:
            try:
                profile = load_profile(path, motor_override=motor)
            except ProfileError:
                continue  # a profile that another motor's limits refuse
            ours = [
                w
                for w in profile.warnings
                if "is in " in w or "lag the ramp" in w or "over_speed" in w
            ]
            assert not ours, (path, motor)


def test_the_refusals_name_every_field_that_may_be_in_the_wrong_unit(tmp_path):
    path = _files(tmp_path, torque_max_nm="10")
    with pytest.raises(ProfileError) as ei:
        load_profile(path)
    assert "write 3.482 or less, or check psi_f_wb (Wb), l_d_h and l_q_h (H)" in str(ei.value)
    path = _files(tmp_path, r_s_ohm="350")
    text = path.read_text().replace("ramp_rpm_s: 2000}", "ramp_rpm_s: 2000, load_nm: 1}", 1)
    path.write_text(text)
    with pytest.raises(ProfileError) as ei:
        load_profile(path)
    assert "or check r_s_ohm (ohm, not mohm), l_d_h, l_q_h (H, not mH)" in str(ei.value)


def test_check_validates_without_running_and_prints_the_datasheet_figures(
    tmp_path, capsys, monkeypatch
):
    path = _files(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert cli_main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"ok: {path} (motor {tmp_path / 'motor.yaml'}")
    # the numbers to hold against the datasheet: Ke 18.5 V/krpm line-line peak, back to front
    assert "Ke 13.08 V/krpm line-line rms, 18.5 peak" in out
    assert "torque at i_max_a 21.2 A on MTPA: 3.482 N m" in out
    assert not (tmp_path / "runs").exists()  # nothing ran, no log
    assert (
        cli_main(["check", str(_files(tmp_path, psi_f_wb="2.5499e-5", torque_max_nm="0.5"))]) == 0
    )
    captured = capsys.readouterr()
    assert captured.out.startswith("ok, with warnings:")
    assert "warning: " in captured.err and "psi_f_wb = 2.5499e-05" in captured.err
    assert cli_main(["check", str(_files(tmp_path, torque_max_nm="10"))]) == 2
    assert "torque_max_nm = 10 is more than" in capsys.readouterr().err


def test_commission_warns_of_the_motor_file_before_it_energises_the_motor(tmp_path, capsys):
    _files(tmp_path, l_d_h="1.1", l_q_h="1.6")
    args = ["commission", "--in-process", "--motor", str(tmp_path / "motor.yaml")]
    args += ["--steps", "offsets,v_dc"]
    args += ["--rig", str(tmp_path / "rig.yaml"), "--log", str(tmp_path / "c.mcap")]
    assert cli_main([*args, "-o", str(tmp_path / "out.yaml")]) == 0
    err = capsys.readouterr().err
    assert f"warning: {tmp_path / 'motor.yaml'}:{LINE['l_d_h']}: l_d_h = 1.1 H" in err
    assert f"{tmp_path / 'motor.yaml'}:{LINE['l_q_h']}: l_q_h = 1.6 H" in err


def test_a_fault_names_the_motor_files_limit(tmp_path):
    from pmsm_hil.recorder import FAULT_BITS, fault_limits_text

    profile = load_profile(_files(tmp_path))
    bits = FAULT_BITS["over_speed"] | FAULT_BITS["heartbeat"]
    assert fault_limits_text(bits, profile.motor) == (
        f"over_speed: beyond speed_trip_rpm 3000 r/min of {tmp_path / 'motor.yaml'}; heartbeat"
    )
    assert "i_trip_a 30 A" in fault_limits_text(FAULT_BITS["over_current"], profile.motor)


def test_run_says_which_limit_tripped(tmp_path, capsys):
    """2450 r/min on a 48 V servo with a rated-load step: the speed overshoots when the load
    comes off and trips over_speed at 3000 r/min."""
    path = _files(tmp_path)
    path.write_text(
        textwrap.dedent(
            """\
            name: servo400-trip
            motor: motor.yaml
            rig: rig.yaml
            segments:
              - {name: up, duration_s: 1.5, speed_rpm: 2450, ramp_rpm_s: 2450}
              - {name: load on, duration_s: 0.5, speed_rpm: 2450, load_nm: 1.1}
              - {name: load off, duration_s: 0.5, speed_rpm: 2450}
            """
        )
    )
    code = cli_main(["run", str(path), "--no-live", "-o", str(tmp_path / "r.mcap")])
    err = capsys.readouterr().err
    assert code == 4, err
    assert f"over_speed: beyond speed_trip_rpm 3000 r/min of {tmp_path / 'motor.yaml'}" in err
    # ... and that the profile's own load step came just before it, with what it does to the speed
    m = re.search(
        r"hint: the fault came ([0-9.]+) ms after segment 2 'load off' began, where the load "
        r"steps off \(1.1 -> 0 N m\): on j_kgm2 ([0-9.e-]+) kg m\^2 the step alone changes the "
        r"speed by ([0-9.]+) r/min per ms",
        err,
    )
    assert m, err
    j = float(m.group(2))
    assert j == load_profile(path).motor.j_kgm2
    assert float(m.group(3)) == pytest.approx(1.1 / j * 30 / math.pi / 1000, rel=1e-3)
    assert 0.0 <= float(m.group(1)) <= 50.0


def test_a_fault_is_put_down_to_a_load_step_only_soon_after_one():
    from types import SimpleNamespace

    from pmsm_hil.analysis.fault_hint import load_step_hint

    seg = SimpleNamespace
    profile = SimpleNamespace(
        motor=SimpleNamespace(j_kgm2=6e-4),
        segments=[
            seg(name="a", load_nm=0.0),
            seg(name="b", load_nm=5.0),
            seg(name="c", load_nm=5.0),
        ],
    )

    def events(seg_i, t_seg, t_fault, what="fault: over_speed"):
        return [
            (0.0, "segment_start", 0, ""),
            (t_seg, "segment_start", seg_i, ""),
            (t_fault, "fault", 2, what),
        ]

    hint = load_step_hint(events(1, 5.0, 5.003), profile)
    assert hint is not None and "steps on (0 -> 5 N m)" in hint
    assert "3.0 ms after segment 1 'b'" in hint and "79.6 r/min per ms" in hint
    assert load_step_hint(events(1, 5.0, 5.2), profile) is None  # long after the step
    assert load_step_hint(events(2, 5.0, 5.003), profile) is None  # no load change there
    assert load_step_hint(events(1, 5.0, 5.003, "fault: heartbeat"), profile) is None
    assert "more current" in load_step_hint(events(1, 5.0, 5.003, "fault: over_current"), profile)
    assert load_step_hint([(5.0, "segment_start", 1, "")], profile) is None  # no fault


def test_a_gimbal_motor_that_the_link_cannot_drive_to_its_limit_is_not_a_unit_slip(tmp_path):
    """7.5 ohm, 1.5 A on 12 V: R i_max_a is 1.6 x v_dc/sqrt 3, by design (the warning fired for
    it); 1000 x that resistance (mohm written as ohm) is still warned of."""
    from pmsm_hil.profiles._source import read_source
    from pmsm_hil.profiles.plausibility import motor_warnings

    path = _files(tmp_path)
    motor = load_profile(path).motor
    src = read_source(str(tmp_path / "motor.yaml"))
    for r_ohm, warned in ((7.5, False), (7500.0, True)):
        gimbal = motor.model_copy(update={"r_s_ohm": r_ohm, "i_max_a": 1.5, "v_dc_v": 12.0})
        texts = [t for t in motor_warnings(gimbal, src, None) if "r_s_ohm" in t]
        assert bool(texts) == warned, texts
    assert "r_s_ohm = 7500 ohm needs 1.125e+04 V" in texts[0] and "1.62e+03 x" in texts[0]


def _sew_last_load(tmp_path, load_nm: str) -> Path:
    """The shipped diagnose-sew profile with its last segment's load (4 N m at 200 r/min, stepped
    on while the speed leaves -450 r/min with -2 N m on) set to ``load_nm``."""
    text = (shipped_root() / "diagnose-sew.yaml").read_text()
    old = "speed_rpm: 200,   ramp_rpm_s: 20000, load_nm: 4.0"
    assert old in text
    text = text.replace(old, f"speed_rpm: 200,   ramp_rpm_s: 20000, load_nm: {load_nm}")
    text = text.replace("motor: motors/", "motor: ").replace("rig: rigs/", "rig: ")
    text = text.replace("sew-cm3c80s.yaml", "sew-cm3c80s")
    path = tmp_path / f"sew-{load_nm}.yaml"
    path.write_text(text)
    return path


def test_a_load_step_that_swings_the_speed_to_its_trip_is_warned_of_and_faults(tmp_path):
    """The speed loop's swing after a load step (its bandwidth and the motor's J): on the SEW
    CM3C80S, 7.5 N m stepped on at -450 r/min with -2 N m taken off swings the speed past its
    720 r/min trip; the warning names the segment's line and field and the swing, and the run
    faults over_speed as it says. The shipped 4 N m step (to -667 r/min) is not warned of."""
    from emu_helpers import run_inproc

    assert not [w for w in load_profile(_sew_last_load(tmp_path, "4.0")).warnings if "swing" in w]
    path = _sew_last_load(tmp_path, "7.5")
    warnings = [w for w in load_profile(path).warnings if "swing" in w]
    assert len(warnings) == 1
    assert re.match(
        rf"{re.escape(str(path))}:\d+: segments\[13\]\.load_nm = 7.5 steps", warnings[0]
    )
    assert "from -2 N m at -450 r/min" in warnings[0] and "speed_trip_rpm 720" in warnings[0]
    assert "about 334 r/min" in warnings[0] and "may fault over_speed" in warnings[0]
    _, result = run_inproc(path, tmp_path / "sew.mcap", seed=1)
    assert result.faults and result.stop_reason == "fault"
