"""A motor file of one's own with the mistakes a datasheet invites (Ke line-line vs phase, poles
for pole pairs, mH for H, a speed the DC link cannot reach or the telemetry cannot carry) is
refused or warned about at load, naming file, line, field and value."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest

from pmsm_hil.profiles import ProfileError, load_motor, load_profile

# A 400 W, 8-pole surface servo for a 48 V link: Ke 8.5 V/krpm line-line rms, R and L per phase
# (half the line-line values), psi_f = 8.5 sqrt(2/3) / (104.72 x 4) Wb.
MOTOR = """
name: lv400
pole_pairs: 4
r_s_ohm: 0.19
l_d_h: 0.00065
l_q_h: 0.00065
psi_f_wb: 0.016568
j_kgm2: 1.0e-4
v_dc_v: 48.0
i_max_a: 30.0
i_trip_a: 40.0
speed_max_rpm: 3000.0
speed_trip_rpm: 3600.0
torque_max_nm: 2.9
v_dc_min_v: 36.0
v_dc_max_v: 60.0
"""

PROFILE = """
name: lv400-walk
motor: motor.yaml
rig: rig.yaml
segments:
  - {name: up, duration_s: 1.0, speed_rpm: 3000, ramp_rpm_s: 6000}
  - {name: load, duration_s: 0.5, speed_rpm: 3000, load_nm: 1.27}
"""

RIG = "name: lv\nv_dc_v: 48.0\n"


def _files(tmp_path: Path, motor: str = MOTOR, profile: str = PROFILE, rig: str = RIG) -> Path:
    (tmp_path / "motor.yaml").write_text(textwrap.dedent(motor).lstrip("\n"))
    (tmp_path / "rig.yaml").write_text(rig)
    path = tmp_path / "p.yaml"
    path.write_text(textwrap.dedent(profile).lstrip("\n"))
    return path


def _motor_with(key: str, value: str) -> str:
    lines = [f"{key}: {value}" if ln.startswith(f"{key}:") else ln for ln in MOTOR.splitlines()]
    return "\n".join(lines) + "\n"


def _problems(path: Path) -> list[str]:
    with pytest.raises(ProfileError) as ei:
        load_profile(path)
    return str(ei.value).splitlines()


def test_the_datasheet_motor_loads_without_warnings(tmp_path):
    profile = load_profile(_files(tmp_path))
    assert profile.warnings == []
    # the steady voltage at rated speed and load: about 25.6 V of the 27.7 V (48 V / sqrt 3)
    u = profile.motor.voltage_needed_v(3000.0, 1.27)
    assert 24.5 < u < 26.5


@pytest.mark.parametrize(
    "key, value, why",
    [
        ("psi_f_wb", "0.0287", "Ke taken as phase rms"),  # sqrt 3 too high: 36 V at 3000 r/min
        ("pole_pairs", "8", "poles written for pole pairs"),
        ("psi_f_wb", "8.5", "Ke in V/krpm written as Wb"),
    ],
)
def test_speed_max_beyond_the_back_emf_reach_is_refused(tmp_path, key, value, why):
    path = _files(tmp_path, motor=_motor_with(key, value))
    problems = _problems(path)
    hits = [p for p in problems if "speed_max_rpm = 3000" in p]
    assert hits, (why, problems)
    msg = hits[0]
    assert msg.startswith(f"{tmp_path / 'motor.yaml'}:11: speed_max_rpm = 3000 ")
    assert "27.71 V" in msg and "v_dc_v 48 V" in msg  # the limit, with where it comes from
    assert "psi_f_wb" in msg and "pole_pairs" in msg  # what to check
    assert "r/min or less" in msg  # what to write instead


def test_speed_max_beyond_the_telemetry_range_is_refused(tmp_path):
    motor = _motor_with("speed_max_rpm", "6000.0").replace("3600.0", "7000.0")
    motor = motor.replace("v_dc_v: 48.0", "v_dc_v: 300.0").replace("60.0", "400.0")
    (tmp_path / "m.yaml").write_text(motor.lstrip("\n"))
    with pytest.raises(ProfileError) as ei:
        load_motor(tmp_path / "m.yaml")
    (msg,) = str(ei.value).splitlines()
    assert msg.startswith(f"{tmp_path / 'm.yaml'}:11: speed_max_rpm = 6000 ")
    assert "3276.7 r/min" in msg and "write 3276.7 or less" in msg


@pytest.mark.parametrize(
    ("key", "value", "line", "top"),
    [("i_max_a", "70.0", 9, "65.534 A"), ("torque_max_nm", "40.0", 13, "32.767 N m")],
)
def test_a_current_or_torque_limit_beyond_the_telemetry_range_is_refused(
    tmp_path, key, value, line, top
):
    motor = _motor_with(key, value).replace("i_trip_a: 40.0", "i_trip_a: 80.0")
    (tmp_path / "m.yaml").write_text(motor.lstrip("\n"))
    with pytest.raises(ProfileError) as ei:
        load_motor(tmp_path / "m.yaml")
    msgs = [m for m in str(ei.value).splitlines() if "the telemetry carries" in m]
    assert len(msgs) == 1 and msgs[0].startswith(f"{tmp_path / 'm.yaml'}:{line}: {key} = ")
    assert f"beyond the {top} that the telemetry carries" in msgs[0]


def test_inductance_in_mh_is_refused_at_the_loaded_segment(tmp_path):
    path = _files(
        tmp_path, motor=_motor_with("l_d_h", "0.65").replace("l_q_h: 0.00065", "l_q_h: 0.65")
    )
    problems = _problems(path)
    (msg,) = [p for p in problems if "segments[1]" in p]
    assert msg.startswith(f"{tmp_path / 'p.yaml'}:6: segments[1].speed_rpm = 3000 ")
    assert "load_nm 1.27" in msg and "l_d_h" in msg and "30.56 V" in msg


def test_a_rig_with_a_lower_link_warns_where_only_overmodulation_reaches(tmp_path):
    # 43 V: 24.83 V linear (v_dc / sqrt 3), 27.38 V six-step (2 v_dc / pi); the load needs 25.5 V
    path = _files(tmp_path, rig="name: lv\nv_dc_v: 43.0\n")
    profile = load_profile(path)
    (w,) = profile.warnings
    assert w.startswith(f"{path}:6: segments[1].speed_rpm = 3000 ")
    assert "24.83 V" in w and "v_dc_v 43 V" in w and "rig.yaml" in w


def test_shipped_profiles_still_load_without_voltage_warnings():
    from pmsm_hil.profiles.shipped import shipped

    for path in shipped("profile"):
        profile = load_profile(path)
        assert not [w for w in profile.warnings if "sqrt 3" in w], path


def test_voltage_needed_is_the_steady_dq_equations():
    m = load_motor(Path(__file__).resolve().parents[1] / "profiles/motors/paper-a-ipmsm.yaml")
    # docs/profiles.md: 15 A at 1500 r/min needs |u| about 153 V peak phase
    t = m.torque_mtpa_nm(15.0)
    assert m.voltage_needed_v(1500.0, t - m.b_visc_nms * 1500 * math.pi / 30) == pytest.approx(
        153, abs=3
    )


def test_the_telemetry_limits_are_the_protocols():
    from pmsm_hil.profiles.motor import TELEMETRY_RANGE, TELEMETRY_SPEED_MAX_RPM
    from pmsm_hil.protocol.generated import BY_NAME, WIRE_TYPES

    which = {"_rpm": "speed_max_rpm", "_a": "i_max_a", "load_nm": "torque_max_nm"}
    seen = set()
    for f in BY_NAME["telem_fast"].fields:
        key = next((k for suffix, k in which.items() if f.name.endswith(suffix)), None)
        if key is None:
            continue
        seen.add(key)
        assert f.type == "i16", f.name
        assert pytest.approx(WIRE_TYPES["i16"][3] * f.scale) == TELEMETRY_RANGE[key][0], f.name
    assert seen == set(TELEMETRY_RANGE)
    assert TELEMETRY_RANGE["speed_max_rpm"][0] == TELEMETRY_SPEED_MAX_RPM
