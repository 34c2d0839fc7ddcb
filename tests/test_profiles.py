"""Profiles, motors and rigs: the shipped files, every class of bad input (the link budget:
tests/test_link_budget.py)."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.profiles import (
    EFFECT_BITS,
    MAX_SEGMENTS,
    Motor,
    Profile,
    ProfileError,
    Rig,
    load_motor,
    load_profile,
    load_rig,
)
from pmsm_hil.profiles.shipped import shipped_file

ROOT = Path(__file__).resolve().parents[1]
PROFILES = ROOT / "profiles"
PAPER_A = PROFILES / "paper-a.yaml"
MOTOR = PROFILES / "motors" / "paper-a-ipmsm.yaml"
RIG = PROFILES / "rigs" / "default.yaml"


# ----------------------------------------------------------------------------------- helpers


def write(path: str | Path, text: str) -> str:
    Path(path).write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return str(path)


GOOD = """
name: test
motor: motors/paper-a-ipmsm.yaml
control:
  ts_s: 50e-6
  rho: 1.0
telemetry:
  fast_hz: 2000
segments:
  - {name: a, duration_s: 1.0, speed_rpm: 100, ramp_rpm_s: 200}
  - {name: b, duration_s: 2.0, speed_rpm: 100, load_nm: 5.0, capture: true}
  - {name: c, duration_s: 1.5, speed_rpm: -200}
"""


def problems_of(path: str, **kw) -> list[str]:
    with pytest.raises(ProfileError) as ei:
        load_profile(path, **kw)
    return str(ei.value).splitlines()


# ----------------------------------------------------------------------------------- shipped files


def test_shipped_motor_is_paper_a():
    m = load_motor(MOTOR)
    assert isinstance(m, Motor)
    assert (m.pole_pairs, m.r_s_ohm, m.l_d_h, m.l_q_h, m.psi_f_wb, m.j_kgm2) == (
        4,
        0.9,
        0.005,
        0.012,
        0.18,
        0.0036,
    )
    assert m.v_dc_v == 540 and m.speed_max_rpm == 1500 and m.i_max_a == 15 and m.i_trip_a == 25
    assert m.speed_trip_rpm == 1800 and m.v_dc_min_v < m.v_dc_v < m.v_dc_max_v
    assert 0 < m.b_visc_nms < 0.01
    # torque_max_nm is what 15 A gives on the MTPA trajectory
    t15 = m.torque_mtpa_nm(15.0)
    assert t15 == pytest.approx(18.31, abs=0.01)
    assert m.torque_max_nm <= t15 and m.torque_max_nm == pytest.approx(t15, rel=0.01)
    i_d, i_q = m.mtpa_currents(15.0)
    assert i_d < 0 and math.hypot(i_d, i_q) == pytest.approx(15.0)
    assert m.yaml_text == MOTOR.read_text(encoding="utf-8")


def test_shipped_rig_effects():
    r = load_rig(RIG)
    assert isinstance(r, Rig)
    assert r.enabled_effects == [
        "dead_time",
        "adc_noise",
        "adc_quantisation",
        "encoder",
        "friction",
    ]
    dt = r.effects["dead_time"]
    assert (dt.dead_time_s, dt.v_drop_v, dt.i_dt_a) == (2e-6, 1.0, 0.5)
    assert r.effects["adc_noise"].i_noise_a == 0.02
    assert r.effects["adc_quantisation"].adc_lsb_a == pytest.approx(100 / 4096)
    assert r.effects["encoder"].lines == 2500 and r.effects["encoder"].counts == 10000
    assert r.effects.get("encoder").offset_e_rad == 0.0
    assert r.effects.get("no_such_effect") is None
    assert r.v_dc_v is None
    assert r.effects_mask == sum(1 << EFFECT_BITS[n] for n in r.enabled_effects)


def test_shipped_defaults_without_paths():
    assert load_motor().name == "paper-a-ipmsm"
    assert load_rig().name == "default"


def test_paper_a_profile():
    p = load_profile(PAPER_A)
    assert isinstance(p, Profile)
    assert p.name == "paper-a" and p.warnings == []
    assert p.motor.name == "paper-a-ipmsm" and p.rig.name == "default"
    assert p.control.ts_s == 50e-6 and p.control.current_ref == "mtpa"
    assert p.control.speed_kp_a_per_rad_s is None and p.control.speed_ki_a_per_rad is None
    assert (
        p.telemetry.fast_hz,
        p.telemetry.params_hz,
        p.telemetry.status_hz,
        p.telemetry.truth_hz,
    ) == (2000, 100, 10, 100)
    assert p.link.baud == 921600
    assert p.total_duration_s == pytest.approx(sum(s.duration_s for s in p.segments))
    assert p.total_duration_s <= 3600
    assert sum(s.capture for s in p.segments) >= 2
    # fig. 13: 15 r/min, load on at t = 5 s and off at t = 10 s
    assert p.reference_at(4.99) == (15.0, 0.0)
    assert p.reference_at(5.0)[1] > 0 and p.reference_at(9.99)[1] > 0
    assert p.reference_at(10.0) == (15.0, 0.0)
    # the other experiments are all there
    plateaus = {s.speed_rpm for s in p.segments}
    assert {15, 240, 1000, 50, 500} <= plateaus
    speeds = [s.speed_rpm for s in p.segments]
    i50 = speeds.index(50)
    assert speeds[i50 + 1 : i50 + 3] == [500, 1000] and all(
        s.ramp_rpm_s > 0 for s in p.segments[i50 : i50 + 3]
    )
    for speed in (240, 1000):
        loads = [s.load_nm for s in p.segments if s.speed_rpm == speed]
        assert max(loads) > 0 and loads[-1] == 0
    # settling: every plateau held >= 1 s after its ramp; every load change followed by >= 1 s
    prev_load = 0.0
    for s in p.segments:
        ramp_time = (
            0.0 if s.ramp_rpm_s == 0 else abs(s.speed_rpm - s.speed_start_rpm) / s.ramp_rpm_s
        )
        assert s.speed_end_rpm == s.speed_rpm
        if s.speed_rpm != 0:
            assert s.duration_s - ramp_time >= 1.0 - 1e-9, s.label
        if s.load_nm != prev_load:
            assert s.duration_s >= 1.0, s.label
        prev_load = s.load_nm
    assert p.segments[-1].speed_rpm == 0


def test_segment_at_and_reference():
    p = load_profile(PAPER_A)
    assert p.segment_at(-0.1) is None and p.segment_at(p.total_duration_s) is None
    assert p.segment_at(0.0).index == 0
    s1 = p.segments[1]
    assert p.segment_at(s1.t_start_s) is s1 and p.segment_at(s1.t_end_s - 1e-9) is s1
    assert p.segment_at(s1.t_end_s).index == 2
    # vectorised reference: ramp from 0 at 15 r/min/s in the first segment
    t = np.array([0.0, 0.5, 1.0, 2.0, 5.5])
    speed, load = p.reference_at(t)
    np.testing.assert_allclose(speed, [0.0, 7.5, 15.0, 15.0, 15.0])
    np.testing.assert_allclose(load, [0, 0, 0, 0, 5.0])
    assert all(math.isnan(x) for x in p.reference_at(-1.0))


def test_profile_metadata_and_attachments():
    p = load_profile(PAPER_A)
    names = [a[0] for a in p.attachments()]
    assert names == ["profile.yaml", "motor.yaml", "rig.yaml"]
    assert p.attachments()[0][2] == PAPER_A.read_bytes()
    assert p.yaml_texts["motor.yaml"] == MOTOR.read_text(encoding="utf-8")
    meta = p.metadata()
    assert meta["profile"]["name"] == "paper-a" and meta["profile"]["file"] == "paper-a.yaml"
    assert meta["motor"]["l_q_h"] == "0.012" and meta["rig"]["dead_time.dead_time_s"] == "2e-06"
    assert meta["rig"]["effects_mask"] == "31"
    assert all(isinstance(v, str) for rec in meta.values() for v in rec.values())
    assert not any("/" in meta[k]["file"] for k in meta)  # no paths of the machine in the log


def test_good_profile_in_workspace(ws):
    p = load_profile(write("good.yaml", GOOD))
    assert p.rig.path == "rigs/default.yaml"  # default rig beside the motors directory
    assert p.motor.path == "motors/paper-a-ipmsm.yaml"
    assert p.control.ts_s == 50e-6  # YAML 1.2 float without a dot
    assert p.segments[1].capture and p.segments[1].flags == 1
    assert p.segments[2].speed_start_rpm == 100 and p.reference_at(3.2) == (-200.0, 0.0)
    assert p.divider(2000) == 10 and p.speed_div == 20
    assert p.v_dc_v == 540


def test_rig_override_and_effect_defaults(ws):
    write(
        "rigs/ideal.yaml",
        """
        name: ideal
        v_dc_v: 500
        effects:
          encoder: {lines: 1024}
        """,
    )
    p = load_profile(write("good.yaml", GOOD), rig_override="rigs/ideal.yaml")
    assert p.rig.name == "ideal" and p.v_dc_v == 500
    assert p.rig.enabled_effects == ["encoder"]  # listed -> on; not listed -> off
    assert not p.rig.enabled("dead_time") and p.rig.effects["dead_time"].dead_time_s == 2e-6
    assert p.rig.effects["encoder"].counts == 4096
    assert p.rig.effects_mask == 1 << EFFECT_BITS["encoder"]


def test_ramp_too_slow_is_a_warning(ws):
    p = load_profile(
        write(
            "slow.yaml",
            """
        name: slow
        motor: motors/paper-a-ipmsm.yaml
        segments:
          - {duration_s: 1.0, speed_rpm: 1000, ramp_rpm_s: 500}
        """,
        )
    )
    assert len(p.warnings) == 1
    assert p.warnings[0].startswith("slow.yaml:4: segments[0]: the ramp")
    assert "reaches only 500 of 1000 r/min" in p.warnings[0]
    assert p.segments[0].speed_end_rpm == 500


# ----------------------------------------------------------------------------------- bad input


def test_out_of_range_speed_names_motor_limit(ws):
    path = write("x.yaml", GOOD.replace("speed_rpm: -200", "speed_rpm: 2400"))
    (msg,) = problems_of(path)
    assert msg == (
        "x.yaml:11: segments[2].speed_rpm = 2400 is beyond the motor's speed_max_rpm 1500 "
        "(motors/paper-a-ipmsm.yaml)"
    )
    with pytest.raises(ProfileError) as ei:
        load_profile(path)
    e = ei.value
    assert (e.file, e.line, e.field, e.value) == ("x.yaml", 11, "segments[2].speed_rpm", 2400)


def test_out_of_range_load_names_motor_limit(ws):
    path = write("x.yaml", GOOD.replace("load_nm: 5.0", "load_nm: -20"))
    (msg,) = problems_of(path)
    assert msg == (
        "x.yaml:10: segments[1].load_nm = -20 is beyond the motor's torque_max_nm 18.3 "
        "(motors/paper-a-ipmsm.yaml)"
    )


def test_malformed_yaml_gives_line_and_column(ws):
    path = write(
        "x.yaml",
        """
        name: x
        motor: motors/paper-a-ipmsm.yaml
        segments:
          - {duration_s: 1, speed_rpm: 10
        """,
    )
    (msg,) = problems_of(path)
    assert msg.startswith("x.yaml:5:1: invalid YAML: expected ',' or '}'")
    path = write("y.yaml", "name: x\n  motor: m.yaml\n")
    (msg,) = problems_of(path)
    assert msg.startswith("y.yaml:2:8: invalid YAML: mapping values are not allowed here")
    Path("t.yaml").write_text("name: x\nsegments:\n\t- {duration_s: 1, speed_rpm: 10}\n")
    (msg,) = problems_of("t.yaml")  # a tab where YAML reads indentation: said how to mend it
    assert msg.startswith("t.yaml:3:1: invalid YAML: found character '\\t'")
    assert msg.endswith("; YAML takes no tab there: replace it with spaces")


def test_a_file_not_in_utf8_is_named_at_the_line_and_column_of_its_octet(ws):
    """A profile or motor file saved as Latin-1 (a degree sign in a comment): its line and column,
    the octet and what comes before it, as for every other problem (it was the file alone)."""
    text = textwrap.dedent(GOOD).lstrip("\n").replace("  rho: 1.0", "  rho: 1.0   # 20 \u00b0C")
    Path("x.yaml").write_bytes(text.encode("latin-1"))
    (msg,) = problems_of("x.yaml")
    assert msg == (
        "x.yaml:5:19: is not UTF-8 text: octet 0xb0 after '  rho: 1.0   # 20 ' (invalid start "
        "byte); save the file as UTF-8"
    )
    motor = Path(MOTOR).read_bytes().replace(b"# Interior", b"# \xb5 Interior", 1)
    Path("motors/paper-a-ipmsm.yaml").write_bytes(motor)
    write("y.yaml", GOOD)
    (msg,) = problems_of("y.yaml")
    assert msg.startswith("motors/paper-a-ipmsm.yaml:1:3: is not UTF-8 text: octet 0xb5 after '# '")


def test_unknown_field_did_you_mean(ws):
    path = write("x.yaml", GOOD.replace("  rho: 1.0", "  rhoo: 1.0"))
    (msg,) = problems_of(path)
    assert msg == "x.yaml:5: control.rhoo = 1 is not a field of control; did you mean 'rho'?"
    path = write("y.yaml", GOOD.replace("  fast_hz: 2000", "  fast_hz: 2000\n  banana: 3"))
    (msg,) = problems_of(path)
    assert msg.startswith(
        "y.yaml:8: telemetry.banana = 3 is not a field of telemetry (known: fast_hz,"
    )
    path = write("z.yaml", GOOD.replace("{name: c,", "{name: c, sped_rpm: 3,"))
    (msg,) = problems_of(path)
    assert (
        msg
        == "z.yaml:11: segments[2].sped_rpm = 3 is not a field of segments[2]; did you mean 'speed_rpm'?"
    )


def test_missing_required_fields(ws):
    path = write(
        "x.yaml",
        """
        motor: motors/paper-a-ipmsm.yaml
        segments:
          - {duration_s: 1.0, speed_rpm: 100}
          - {speed_rpm: 100}
        """,
    )
    msgs = problems_of(path)
    assert msgs == [
        "x.yaml:1: name is missing (required: profile name)",
        "x.yaml:4: segments[1].duration_s is missing (required: length of the segment, s)",
    ]


def test_wrong_types(ws):
    path = write(
        "x.yaml",
        GOOD.replace("rho: 1.0", "rho: fast")
        .replace("capture: true", "capture: 1")
        .replace("ts_s: 50e-6", "ts_s: '50e-6'")
        .replace("current_ref", "x"),
    )
    msgs = problems_of(path)
    assert msgs == [
        "x.yaml:4: control.ts_s = '50e-6' is not a number (write numbers without quotes)",
        "x.yaml:5: control.rho = 'fast' is not a number",  # no quotes to remove: no hint
        "x.yaml:10: segments[1].capture = 1 is not true or false",
    ]
    path = write("y.yaml", GOOD.replace("  rho: 1.0", "  current_ref: mtp"))
    assert problems_of(path) == [
        "y.yaml:5: control.current_ref = 'mtp' is not one of 'mtpa' or 'id_zero'"
    ]
    path = write("z.yaml", GOOD.replace("telemetry:\n  fast_hz: 2000", "telemetry: 2000"))
    assert problems_of(path) == [
        "z.yaml:6: telemetry = 2000 must be a mapping of `key: value` lines"
    ]


def test_ranges_and_rates(ws):
    path = write(
        "x.yaml",
        GOOD.replace("ts_s: 50e-6", "ts_s: 10e-6")
        .replace("duration_s: 1.0", "duration_s: 0")
        .replace("ramp_rpm_s: 200", "ramp_rpm_s: -5"),
    )
    msgs = problems_of(path)
    assert msgs == [
        "x.yaml:4: control.ts_s = 1e-05 is outside the allowed range [2e-05, 0.001] s",
        "x.yaml:9: segments[0].duration_s = 0 is outside the allowed range (0, 3600] s",
        "x.yaml:9: segments[0].ramp_rpm_s = -5 is outside the allowed range [0, 1000000] r/min/s",
    ]
    path = write(
        "y.yaml",
        GOOD.replace("fast_hz: 2000", "fast_hz: 3000\n  params_hz: 30000").replace(
            "rho: 1.0", "rho: 1.0\n  speed_loop_hz: 1500"
        ),
    )
    msgs = problems_of(path)
    assert msgs == [
        "y.yaml:6: control.speed_loop_hz = 1500 does not divide the control rate 20000 Hz (1/control.ts_s); "
        "nearest valid: 1428.57 or 1538.46 Hz",
        "y.yaml:8: telemetry.fast_hz = 3000 does not divide the control rate 20000 Hz (1/control.ts_s); "
        "nearest valid: 2857.14 or 3333.33 Hz",
        "y.yaml:9: telemetry.params_hz = 30000 is above the control rate 20000 Hz (1/control.ts_s)",
    ]
    # another control rate: 1/ts_s = 10 kHz, 2000 Hz still divides, 3000 does not
    path = write("z.yaml", GOOD.replace("ts_s: 50e-6", "ts_s: 100e-6"))
    assert load_profile(path).control_hz == pytest.approx(10000)


def test_total_duration_limit(ws):
    segs = "\n".join("  - {duration_s: 1000, speed_rpm: 10}" for _ in range(4))
    path = write("x.yaml", "name: x\nmotor: motors/paper-a-ipmsm.yaml\nsegments:\n" + segs + "\n")
    assert problems_of(path) == ["x.yaml:3: segments last 4000 s in total, beyond the 3600 s limit"]


def test_speed_gains_both_or_neither(ws):
    path = write("x.yaml", GOOD.replace("rho: 1.0", "rho: 1.0\n  speed_kp_a_per_rad_s: 0.5"))
    (msg,) = problems_of(path)
    assert msg.startswith(
        "x.yaml:6: control.speed_kp_a_per_rad_s = 0.5 is given but control.speed_ki_a_per_rad is not"
    )


def test_duplicate_key(ws):
    path = write("x.yaml", GOOD.replace("name: test\n", "name: test\nname: again\n"))
    assert problems_of(path) == ["x.yaml:2: name is given twice (first on line 1)"]


def test_empty_and_non_mapping_files(ws):
    assert problems_of(write("x.yaml", "")) == ["x.yaml:1: the profile is empty"]
    assert problems_of(write("y.yaml", "- a\n- b\n")) == [
        "y.yaml:1: the profile must be a mapping of `key: value` lines, not a list"
    ]
    (msg,) = problems_of("nothing.yaml")
    assert msg.startswith("nothing.yaml: cannot read the profile:")


def test_missing_motor_file_reported_at_the_reference(ws):
    path = write("x.yaml", GOOD.replace("motors/paper-a-ipmsm.yaml", "motors/nope.yaml"))
    msgs = problems_of(path)
    assert msgs[0].startswith(
        "x.yaml:2: motor = 'motors/nope.yaml' names a motor file that cannot be read: "
        "motors/nope.yaml:"
    )
    assert len(msgs) == 1  # the default rig is found next to motors/ all the same


def test_missing_default_rig_is_the_shipped_default_with_a_note(ws):
    (ws / "rigs" / "default.yaml").unlink()
    p = load_profile(write("x.yaml", GOOD))
    assert p.rig.path == shipped_file("rigs/default.yaml")
    assert any(
        w.startswith("x.yaml: no rig given, and nothing at rigs/default.yaml") for w in p.warnings
    )


def test_motor_file_problems_name_the_motor_file(ws):
    text = (ws / "motors" / "paper-a-ipmsm.yaml").read_text()
    text = (
        text.replace("i_trip_a: 25.0", "i_trip_a: 12.0")
        .replace("torque_max_nm: 18.3", "torque_max_nm: 25")
        .replace("j_kgm2: 0.0036", "j_kgm2: 4.5 g m^2")
        .replace("r_s_ohm: 0.9", "r_s_ohms: 0.9")
    )
    (ws / "motors" / "bad.yaml").write_text(text)
    msgs = problems_of(write("x.yaml", GOOD.replace("paper-a-ipmsm", "bad")))
    lines = {
        yaml_line(ws / "motors" / "bad.yaml", k)
        for k in ("j_kgm2", "r_s_ohms", "i_trip_a", "torque_max_nm")
    }
    assert all(m.startswith("motors/bad.yaml:") for m in msgs)
    assert {int(m.split(":")[1]) for m in msgs} >= lines
    joined = "\n".join(msgs)
    assert "j_kgm2 = '4.5 g m^2' is not a number" in joined
    assert "r_s_ohms = 0.9 is not a field of the file; did you mean 'r_s_ohm'?" in joined
    assert "r_s_ohm is missing (required" in joined
    assert "i_trip_a = 12 must be above i_max_a 15 A" in joined
    assert (
        "torque_max_nm = 25 is more than the 18.31 N m that i_max_a 15 A gives on the MTPA trajectory"
        in joined
    )
    with pytest.raises(ProfileError) as ei:
        load_motor(ws / "motors" / "bad.yaml")
    assert ei.value.file.endswith("bad.yaml") and len(ei.value.problems) >= 4


def yaml_line(path: Path, key: str) -> int:
    for i, line in enumerate(path.read_text().splitlines(), 1):
        if line.startswith(key + ":"):
            return i
    raise AssertionError(key)


def test_rig_problems(ws):
    write(
        "rigs/bad.yaml",
        """
        name: bad
        v_dc_v: 800
        effects:
          dead_tme: {enabled: true}
          encoder: {lines: 0}
          adc_noise: true
        """,
    )
    msgs = problems_of(write("x.yaml", GOOD), rig_override="rigs/bad.yaml")
    assert msgs == [
        "rigs/bad.yaml:4: effects.dead_tme = {enabled: true} is not a field of effects; did you mean 'dead_time'?",
        "rigs/bad.yaml:5: effects.encoder.lines = 0 is outside the allowed range [1, 1000000]",
        "rigs/bad.yaml:6: effects.adc_noise = true must be a mapping of `key: value` lines",
    ]
    write("rigs/hv.yaml", "name: hv\nv_dc_v: 800\n")
    assert problems_of(write("y.yaml", GOOD.replace("motor:", "rig: rigs/hv.yaml\nmotor:"))) == [
        "rigs/hv.yaml:2: v_dc_v = 800 is outside the motor's DC-link trip limits v_dc_min_v 400 .. "
        "v_dc_max_v 750 V (motors/paper-a-ipmsm.yaml)"
    ]


def test_several_problems_all_listed(ws):
    path = write(
        "x.yaml",
        GOOD.replace("speed_rpm: -200", "speed_rpm: 2400")
        .replace("rho: 1.0", "rho: -1")
        .replace("load_nm: 5.0", "load_nm: 50"),
    )
    with pytest.raises(ProfileError) as ei:
        load_profile(path)
    e = ei.value
    assert len(e.problems) == 3 and len(str(e).splitlines()) == 3
    assert [p.line for p in e.problems] == [5, 10, 11]
    assert (e.file, e.line, e.field, e.value) == ("x.yaml", 5, "control.rho", -1)


def test_segment_limit_matches_the_firmware(ws):
    header = ROOT / "firmware" / "core" / "profile_exec.h"
    if header.exists():
        import re

        m = re.search(r"#define\s+PROFILE_MAX_SEGMENTS\s+(\d+)", header.read_text())
        assert m and int(m.group(1)) == MAX_SEGMENTS
    segs = "\n".join("  - {duration_s: 0.1, speed_rpm: 10}" for _ in range(MAX_SEGMENTS + 1))
    path = write("x.yaml", "name: x\nmotor: motors/paper-a-ipmsm.yaml\nsegments:\n" + segs + "\n")
    assert problems_of(path) == [
        f"x.yaml:3: segments = [{MAX_SEGMENTS + 1} items] must have at most {MAX_SEGMENTS} items"
    ]


def test_a_unit_after_a_number_and_yaml11_booleans_are_pointed_out(ws):
    """`ts_s: 50us` is not quoted: the hint is the unit, not the quotes; `capture: yes` is true to
    this reader (YAML 1.1) and text to YAML 1.2, so it is refused; a misspelt shipped motor name
    gets the name it was likely meant to be."""
    path = write(
        "x.yaml", GOOD.replace("ts_s: 50e-6", "ts_s: 50us").replace("capture: true", "capture: yes")
    )
    msgs = "\n".join(problems_of(path))
    assert "control.ts_s = '50us' is not a number (write the number alone: the unit is in" in msgs
    assert "capture = 'yes' is true to this reader (YAML 1.1) and text to YAML 1.2" in msgs
    typo = write("y.yaml", "name: y\nmotor: paper-a-ipmsn\nsegments:\n  - {duration_s: 1}\n")
    assert "did you mean the shipped motor 'paper-a-ipmsm'?" in "\n".join(problems_of(typo))
