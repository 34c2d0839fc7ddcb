"""Sensorless operation on the emulator (docs/sensorless.md): the MRAS closing the loop under FOC
and under MPCC converges from a wrong initial angle, loss of lock trips a fault that stops the
motor and leaves a readable log, and the profile's new options are validated."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
from emu_helpers import run_inproc

from pmsm_hil.control_design import device_config
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import ProfileError, load_profile
from pmsm_hil.protocol import generated as gen
from pmsm_hil.recorder import FAULT_BITS

ROOT = Path(__file__).resolve().parents[1]
MOTOR_B = ROOT / "profiles" / "motors" / "paper-b-spmsm.yaml"
MOTOR_A = ROOT / "profiles" / "motors" / "paper-a-ipmsm.yaml"
RIG = ROOT / "profiles" / "rigs" / "default.yaml"


def profile_text(control: str, segments: str, motor: Path = MOTOR_B, ts: str = "100.0e-6") -> str:
    def block(text: str, indent: str) -> str:
        lines = textwrap.dedent(text).strip().splitlines()
        return "\n".join(indent + x for x in lines)

    return (
        f"name: sensorless-test\nmotor: {motor}\nrig: {RIG}\ncontrol:\n  ts_s: {ts}\n"
        + block(control, "  ")
        + "\ntelemetry: {fast_hz: 2000, params_hz: 10, status_hz: 10, truth_hz: 100, est_hz: 500}"
        + "\nsegments:\n"
        + block(segments, "  ")
        + "\n"
    )


def wrap(x):
    return (np.asarray(x, float) + np.pi) % (2 * np.pi) - np.pi


def angle_error(log, t0: float, t1: float) -> np.ndarray:
    tel = log.topic("/pmsm/telemetry")
    t = np.asarray(tel["t_s"])
    m = (t >= t0) & (t < t1)
    return wrap(np.asarray(tel["theta_e_est_rad"])[m] - np.asarray(tel["theta_e_rad"])[m])


@pytest.mark.parametrize(
    "ctrl,motor,ts,speed,theta0",
    [
        ("foc", MOTOR_B, "100.0e-6", 1000, 2.0),
        ("foc", MOTOR_B, "100.0e-6", -1000, -2.2),
        ("mpcc", MOTOR_A, "50.0e-6", 800, 1.8),
    ],
)
def test_mras_converges_from_a_wrong_initial_angle_and_closes_the_loop(
    tmp_path, ctrl, motor, ts, speed, theta0
):
    """The estimator starts 2 rad off while the encoder spins the motor up; by the time the
    segment hands the loop to it, it has converged, and the run stays on it within 0.05 rad."""
    path = tmp_path / "p.yaml"
    path.write_text(
        profile_text(
            f"""
            current_ctrl: {ctrl}
            current_ref: id_zero
            angle_src: mras
            estimator: {{theta0_rad: {theta0}, min_speed_rpm: 75}}
            """,
            f"""
            - {{name: spin-up, duration_s: 0.25, speed_rpm: {speed}, ramp_rpm_s: 10000, angle_encoder: true}}
            - {{name: sensorless, duration_s: 0.3, speed_rpm: {speed}, load_nm: 1.0}}
            - {{name: sensorless 2, duration_s: 0.2, speed_rpm: {speed * 0.7}, ramp_rpm_s: 3000}}
            """,
            motor,
            ts,
        )
    )
    out = tmp_path / "run.mcap"
    _profile, result = run_inproc(path, out, seed=7)
    assert result.faults == 0 and result.state == "done"
    log = read_log(out)
    est = log.topic("/pmsm/estimator")
    t = np.asarray(est["t_s"])
    err = np.asarray(est["theta_err_rad"])
    assert abs(err[0]) > 1.5  # it did start far off
    assert set(est["estimator"]) == {"mras"}
    in_loop = np.asarray(est["in_loop"], bool)
    assert not in_loop[t < 0.25].any() and in_loop[(t > 0.26) & (t < 0.7)].all()
    running = in_loop & (t < 0.75)  # then the stop ramp: out of range, PWM off, the rotor coasts
    assert np.asarray(est["locked"], bool)[running].all()
    e = angle_error(log, 0.25, 0.75)
    assert np.max(np.abs(e)) < 0.05
    tel = log.topic("/pmsm/telemetry")
    tt = np.asarray(tel["t_s"])
    m = (tt > 0.45) & (tt < 0.55)
    assert np.mean(np.asarray(tel["speed_rpm"])[m]) == pytest.approx(speed, abs=0.02 * abs(speed))


def test_lost_lock_trips_a_fault_that_stops_the_motor(tmp_path):
    """Below its speed range the MRAS is not locked; closing the loop on it there trips lost_lock
    after the timeout: PWM off, a fault event, a readable log."""
    path = tmp_path / "p.yaml"
    path.write_text(
        profile_text(
            """
            current_ctrl: foc
            current_ref: id_zero
            angle_src: mras
            estimator: {min_speed_rpm: 75, lock_timeout_s: 0.02}
            """,
            """
            - {name: spin-up, duration_s: 0.1, speed_rpm: 600, angle_encoder: true}
            - {name: sensorless, duration_s: 0.1, speed_rpm: 600}
            - {name: too slow, duration_s: 0.5, speed_rpm: 20, ramp_rpm_s: 20000}
            """,
        )
    )
    out = tmp_path / "run.mcap"
    _, result = run_inproc(path, out, seed=3)
    assert result.state == "fault" and result.stop_reason == "fault"
    assert result.faults & FAULT_BITS["lost_lock"]
    log = read_log(out)
    ev = log.topic("/pmsm/events")
    texts = list(ev["text"])
    assert any("lost_lock" in x for x in texts)
    t_fault = float(
        np.asarray(ev["t_s"])[next(i for i, k in enumerate(ev["kind"]) if k == "fault")]
    )
    assert 0.2 < t_fault < 0.7
    est = log.topic("/pmsm/estimator")
    te = np.asarray(est["t_s"])
    locked = np.asarray(est["locked"], bool)
    assert locked[(te > 0.15) & (te < 0.2)].all()
    assert not locked[(te > t_fault - 0.015) & (te < t_fault)].any()
    # after the trip the inverter is off: no further telemetry as running, the currents decay
    st = log.topic("/pmsm/status")
    assert list(st["state"])[-1] == "fault"
    tel = log.topic("/pmsm/telemetry")
    assert np.asarray(tel["t_s"])[-1] <= t_fault + 1e-3


def test_the_configuration_carries_the_selections():
    path = ROOT / "profiles" / "paper-b.yaml"
    p = load_profile(str(path))
    _, ctrl = device_config(p)
    assert ctrl["current_ctrl"] == gen.ENUMS["current_ctrl"]["foc"]
    assert ctrl["angle_src"] == gen.ENUMS["angle_src"]["mras"]
    assert ctrl["est_min_speed_rpm"] == 75
    assert ctrl["foc_bw_rad_s"] == pytest.approx(2 * np.pi / (20 * 100e-6))
    assert ctrl["est_div"] == 20
    budget = p.link_budget()
    assert budget["streams"]["telem_est"]["rate_hz"] == 500 and budget["load"] < 1.0
    a = load_profile(str(ROOT / "profiles" / "paper-a.yaml"))
    assert a.link_budget()["streams"]["telem_est"]["octets_s"] == 0  # the encoder: no frame


@pytest.mark.parametrize(
    "control,field,value",
    [
        ("current_ctrl: pid", "control.current_ctrl", "pid"),
        ("angle_src: sensorless", "control.angle_src", "sensorless"),
        ("mpcc_candidates: some", "control.mpcc_candidates", "some"),
        ("estimator: {bw_rad_s: -5}", "control.estimator.bw_rad_s", "-5"),
        ("estimator: {lock_timeout_s: 99}", "control.estimator.lock_timeout_s", "99"),
    ],
)
def test_bad_sensorless_options_are_reported_with_file_line_and_value(
    tmp_path, control, field, value
):
    path = tmp_path / "bad.yaml"
    path.write_text(profile_text(control, "- {name: a, duration_s: 0.1, speed_rpm: 100}"))
    with pytest.raises(ProfileError) as ei:
        load_profile(str(path))
    msg = str(ei.value)
    line = next(i + 1 for i, x in enumerate(path.read_text().splitlines()) if x.strip() == control)
    assert f"bad.yaml:{line}" in msg and field in msg and value in msg


@pytest.mark.parametrize("cands", ["adjacent", "all"])
def test_mpcc_candidate_set_is_selectable(tmp_path, cands):
    """Paper A Table 1's set changes exactly one leg per period (single-leg flips); all 8 states
    also switch two or three legs at once, or none."""
    path = tmp_path / "p.yaml"
    path.write_text(
        profile_text(
            f"""
            current_ctrl: mpcc
            mpcc_candidates: {cands}
            """,
            """
            - {name: up, duration_s: 0.2, speed_rpm: 240, ramp_rpm_s: 2400, capture: true}
            - {name: hold, duration_s: 0.1, speed_rpm: 240}
            """,
            MOTOR_A,
            "50.0e-6",
        )
    )
    out = tmp_path / "run.mcap"
    _, result = run_inproc(path, out, seed=5)
    assert result.faults == 0 and result.state == "done"
    cap = read_log(out).topic("/pmsm/capture")
    code = (
        np.asarray(cap["s_a"], int)
        | (np.asarray(cap["s_b"], int) << 1)
        | (np.asarray(cap["s_c"], int) << 2)
    )
    assert len(code) > 500
    flips = np.array([bin(int(x)).count("1") for x in code[1:] ^ code[:-1]])
    if cands == "adjacent":
        assert np.all(flips == 1)
    else:
        assert np.any(flips != 1)
