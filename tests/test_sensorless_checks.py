"""A sensorless profile checked against its motor file before the run (docs/sensorless.md): the
ripple PLL on a motor without saliency and a hybrid whose MRAS could never take over are bad input
naming file, line, field and value; a start on the MRAS from standstill without an I/f start is a
warning (the emulator's rotor rests where the estimator starts, a rig's need not)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.profiles import ProfileError, load_profile

ROOT = Path(__file__).resolve().parents[1]
MOTORS = ROOT / "profiles" / "motors"
RIG = ROOT / "profiles" / "rigs" / "default.yaml"


def _profile(tmp_path: Path, motor: Path, angle_src: str, first_segment: str) -> Path:
    path = tmp_path / "p.yaml"
    path.write_text(
        f"name: p\nmotor: {motor}\nrig: {RIG}\n"
        f"control:\n  ts_s: 100.0e-6\n  current_ctrl: foc\n  angle_src: {angle_src}\n"
        "telemetry: {fast_hz: 2000, params_hz: 10, status_hz: 10, truth_hz: 100, est_hz: 500}\n"
        "segments:\n"
        f"  - {first_segment}\n"
        "  - {name: b, duration_s: 0.1, speed_rpm: 600}\n"
    )
    return path


def _line(path: Path, text: str) -> int:
    return next(i + 1 for i, x in enumerate(path.read_text().splitlines()) if text in x)


@pytest.mark.parametrize("angle_src", ["ripple_pll", "hybrid"])
def test_ripple_pll_on_a_motor_without_saliency_is_bad_input(tmp_path, angle_src):
    # paper B's surface motor: L_d = L_q and no flux map, nothing for the PLL's phase detector
    path = _profile(
        tmp_path,
        MOTORS / "paper-b-spmsm.yaml",
        angle_src,
        "{name: a, duration_s: 0.1, speed_rpm: 100}",
    )
    with pytest.raises(ProfileError) as ei:
        load_profile(str(path))
    msg = str(ei.value)
    assert f"p.yaml:{_line(path, 'angle_src')}: control.angle_src = '{angle_src}'" in msg
    assert "l_d_h = l_q_h = 0.0085 H" in msg and "use mras" in msg
    # a salient motor is accepted
    ok = _profile(
        tmp_path,
        MOTORS / "paper-a-ipmsm.yaml",
        angle_src,
        "{name: a, duration_s: 0.1, speed_rpm: 100}",
    )
    load_profile(str(ok))


def test_a_hybrid_handover_above_the_motors_top_speed_is_bad_input(tmp_path):
    motor = tmp_path / "m.yaml"
    motor.write_text((MOTORS / "paper-a-ipmsm.yaml").read_text() + "hybrid_mras_on_rpm: 2000.0\n")
    path = _profile(tmp_path, motor, "hybrid", "{name: a, duration_s: 0.1, speed_rpm: 100}")
    with pytest.raises(ProfileError) as ei:
        load_profile(str(path))
    msg = str(ei.value)
    assert f"m.yaml:{_line(motor, 'hybrid_mras_on_rpm')}: hybrid_mras_on_rpm = 2000" in msg
    assert "speed_max_rpm 1500" in msg and "write less than 1500" in msg
    # the same motor file is fine for an angle source that does not hand over
    load_profile(
        str(_profile(tmp_path, motor, "ripple_pll", "{name: a, duration_s: 0.1, speed_rpm: 100}"))
    )


def test_a_start_on_the_mras_without_an_if_start_is_warned_about(tmp_path):
    motor = tmp_path / "m.yaml"
    text = (MOTORS / "paper-b-spmsm.yaml").read_text()
    motor.write_text("".join(x for x in text.splitlines(True) if not x.startswith("if_start_")))
    first = "{name: a, duration_s: 0.1, speed_rpm: 600}"
    path = _profile(tmp_path, motor, "mras", first)
    (warning,) = [w for w in load_profile(str(path)).warnings if "standstill" in w]
    assert warning.startswith(f"{path}:{_line(path, 'name: a')}: segments[0]")
    assert "if_start_current_a" in warning and "angle_encoder: true" in warning
    # on the encoder first, or with the motor file's I/f start: no warning
    on_encoder = "{name: a, duration_s: 0.1, speed_rpm: 600, angle_encoder: true}"
    for p in (
        _profile(tmp_path, motor, "mras", on_encoder),
        _profile(tmp_path, MOTORS / "paper-b-spmsm.yaml", "mras", first),
    ):
        assert not [w for w in load_profile(str(p)).warnings if "standstill" in w]


def test_an_estimator_minimum_speed_above_the_motors_top_speed_is_bad_input(tmp_path):
    path = _profile(
        tmp_path,
        MOTORS / "paper-b-spmsm.yaml",
        "mras",
        "{name: a, duration_s: 0.1, speed_rpm: 100}",
    )
    text = path.read_text().replace("  angle_src: mras\n", "  angle_src: mras\n  estimator:\n")
    for value, bad in (("5000", True), ("1500", True), ("75", False)):
        path.write_text(text.replace("estimator:\n", f"estimator:\n    min_speed_rpm: {value}\n"))
        if not bad:
            load_profile(str(path))
            continue
        with pytest.raises(ProfileError) as ei:
            load_profile(str(path))
        assert (
            f"p.yaml:{_line(path, 'min_speed_rpm')}: control.estimator.min_speed_rpm = {value} is "
            "not below the motor's speed_max_rpm 1500 r/min"
        ) in str(ei.value)


@pytest.mark.parametrize("angle_src", ["ripple_pll", "hybrid"])
def test_the_ripple_pll_on_a_motor_without_a_flux_map_is_warned_about(tmp_path, angle_src):
    # paper A's motor without its map: the polarity test has only the textbook sign, which the
    # default rig cannot show (lost_lock at 0.11 s) and lab-typical's map contradicts (the wrong
    # pole, over_speed at 0.14 s), also when the first segment runs on the encoder
    for first in (
        "{name: a, duration_s: 0.1, speed_rpm: 100}",
        "{name: a, duration_s: 0.1, speed_rpm: 100, angle_encoder: true}",
    ):
        path = _profile(tmp_path, MOTORS / "paper-a-ipmsm.yaml", angle_src, first)
        (warning,) = [w for w in load_profile(str(path)).warnings if "polarity" in w]
        assert warning.startswith(f"{path}:{_line(path, 'angle_src')}: control.angle_src")
        assert "paper-a-ipmsm.yaml has no flux_map" in warning and "flux_map" in warning
    # with the motor's map: no warning
    path = _profile(tmp_path, MOTORS / "paper-a-ipmsm-measured.yaml", angle_src, first)
    assert not [w for w in load_profile(str(path)).warnings if "polarity" in w]


def test_a_segment_on_the_mras_below_its_minimum_speed_is_warned_about(tmp_path):
    # a reversal and a stop to standstill on the MRAS trip lost_lock (paper B's motor, seed 1)
    path = _profile(
        tmp_path,
        MOTORS / "paper-b-spmsm.yaml",
        "mras",
        "{name: a, duration_s: 0.3, speed_rpm: 600}",
    )
    text = path.read_text()
    path.write_text(
        text
        + "  - {name: rev, duration_s: 1.0, speed_rpm: -600, ramp_rpm_s: 2000}\n"
        + "  - {name: stop, duration_s: 0.5, speed_rpm: 0, ramp_rpm_s: 2000}\n"
    )
    below = [w for w in load_profile(str(path)).warnings if "minimum speed" in w]
    assert len(below) == 2
    assert below[0].startswith(f"{path}:{_line(path, 'name: rev')}: segments[2] reverses through 0")
    assert below[1].startswith(f"{path}:{_line(path, 'name: stop')}: segments[3] goes to 0 r/min")
    assert "75 r/min" in below[0] and "angle_encoder: true" in below[0]
    # the same segments on the encoder, and a stop that stays above the range: no warning
    path.write_text(
        text
        + "  - {name: rev, duration_s: 1.0, speed_rpm: -600, ramp_rpm_s: 2000, angle_encoder: true}\n"
        + "  - {name: slow, duration_s: 0.5, speed_rpm: -300, ramp_rpm_s: 2000}\n"
    )
    assert [w for w in load_profile(str(path)).warnings if "minimum speed" in w] == []


@pytest.mark.parametrize(
    ("key", "value", "text"),
    [
        ("if_start_current_a", "30", "is beyond i_max_a 10 A"),
        ("if_handover_rpm", "2000", "is beyond speed_max_rpm 1500 r/min"),
    ],
)
def test_an_if_start_the_firmware_would_refuse_is_bad_input(tmp_path, key, value, text):
    # was accepted, then "device refused config_sensorless (bad_value)" with the message's fields
    motor = tmp_path / "m.yaml"
    lines = (MOTORS / "paper-b-spmsm.yaml").read_text().splitlines(True)
    motor.write_text("".join(f"{key}: {value}\n" if x.startswith(key) else x for x in lines))
    path = _profile(tmp_path, motor, "mras", "{name: a, duration_s: 0.1, speed_rpm: 600}")
    with pytest.raises(ProfileError) as ei:
        load_profile(str(path))
    assert f"m.yaml:{_line(motor, key)}: {key} = {value} {text}" in str(ei.value)
