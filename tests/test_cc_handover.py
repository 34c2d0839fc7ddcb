"""A segment may name its current controller (`segments[i].current_ctrl`): the firmware hands the
current-control slot over at the segment start without a step in voltage or current
(docs/control.md), and the profile and the firmware refuse what makes no sense."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from emu_helpers import run_inproc

from pmsm_hil.device import DeviceSpec, open_device
from pmsm_hil.errors import DeviceError
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import ProfileError, load_profile
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import configure

ROOT = Path(__file__).resolve().parents[1]
MOTOR_A = ROOT / "profiles" / "motors" / "paper-a-ipmsm.yaml"
LAB = ROOT / "profiles" / "rigs" / "lab-typical.yaml"
T_SWITCH_S = 0.9  # start of the segment that changes controller


def handover_profile(tmp_path: Path, first: str, then: str) -> Path:
    """Under a 9 N m load at 1000 r/min, the controller changes at T_SWITCH_S; a control-rate
    capture is triggered there."""
    p = tmp_path / f"{first}-{then}.yaml"
    p.write_text(
        f"name: handover\nmotor: {MOTOR_A}\ncontrol: {{current_ctrl: {first}}}\nsegments:\n"
        "  - {duration_s: 0.6, speed_rpm: 1000, ramp_rpm_s: 4000}\n"
        "  - {duration_s: 0.3, speed_rpm: 1000, load_nm: 9}\n"
        f"  - {{duration_s: 0.1, speed_rpm: 1000, load_nm: 9, current_ctrl: {then}, "
        "capture: true}\n"
    )
    return p


def q_current_error(log) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Control-rate capture: time, d and q current errors against the (held) references."""
    cap = log.topic("/pmsm/capture")
    t = np.asarray(cap["t_s"])
    th = np.asarray(cap["theta_e_rad"])
    ia, ib, ic = (np.asarray(cap[k]) for k in ("i_a_a", "i_b_a", "i_c_a"))
    i_al = (2 * ia - ib - ic) / 3
    i_be = (ib - ic) / np.sqrt(3)
    i_d = np.cos(th) * i_al + np.sin(th) * i_be
    i_q = -np.sin(th) * i_al + np.cos(th) * i_be
    tel = log.topic("/pmsm/telemetry")
    ref_d = np.interp(t, tel["t_s"], tel["i_d_ref_a"])
    ref_q = np.interp(t, tel["t_s"], tel["i_q_ref_a"])
    return t, i_d - ref_d, i_q - ref_q


def window(t: np.ndarray, e: np.ndarray, a_s: float, b_s: float) -> np.ndarray:
    m = (t >= T_SWITCH_S + a_s) & (t < T_SWITCH_S + b_s)
    assert m.sum() > 10, "the capture does not cover the window"
    return e[m]


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.mark.parametrize("rig,seed", [(None, 5), (LAB, 6)])
def test_mpcc_to_foc_hands_over_without_a_current_step(tmp_path, rig, seed):
    """FOC starts from the MPCC's applied vector and its mean dq voltage. Where the firmware's
    inverter model is the plant's (default rig), its first milliseconds track as well as its
    steady state; a cold start (integrators at zero, no applied voltage) doubles the q error in
    that window. On lab-typical the inverter the firmware is not told about leaves FOC a bias
    that its integrator removes over some 30 ms, far inside the MPCC's own ripple."""
    _, res = run_inproc(
        handover_profile(tmp_path, "mpcc", "foc"), tmp_path / "r.mcap", seed=seed, rig=rig
    )
    assert (res.state, res.faults) == ("done", 0)
    t, e_d, e_q = q_current_error(read_log(tmp_path / "r.mcap"))
    before = window(t, e_q, -0.01, 0.0)  # the MPCC's own ripple
    first_ms = np.abs(window(t, e_q, 0.0, 0.001)).max()
    settling = window(t, e_q, 0.001, 0.005)
    steady = window(t, e_q, 0.005, 0.05)
    assert first_ms <= np.abs(before).max()
    assert rms(settling) <= 0.5 * rms(before)
    assert rms(steady) < 0.25 * rms(before)  # it is FOC now: no FCS ripple
    if rig is None:
        assert rms(settling) <= 1.6 * rms(steady), (rms(settling), rms(steady))
        assert abs(float(np.mean(settling))) <= 0.06
        assert rms(window(t, e_d, 0.001, 0.005)) <= 1.6 * rms(window(t, e_d, 0.005, 0.05)) + 0.02


@pytest.mark.parametrize("rig,seed", [(None, 5), (LAB, 6)])
def test_foc_to_mpcc_hands_over_within_the_mpcc_ripple(tmp_path, rig, seed):
    """The MPCC's first prediction uses the voltage FOC applies during that period, so the error
    right after the handover is no larger than the MPCC's own steady ripple."""
    _, res = run_inproc(
        handover_profile(tmp_path, "foc", "mpcc"), tmp_path / "r.mcap", seed=seed, rig=rig
    )
    assert (res.state, res.faults) == ("done", 0)
    t, _e_d, e_q = q_current_error(read_log(tmp_path / "r.mcap"))
    before = window(t, e_q, -0.01, 0.0)
    after = np.abs(window(t, e_q, 0.0, 0.005)).max()
    steady = window(t, e_q, 0.005, 0.05)
    assert rms(before) < 0.25 * rms(steady)  # FOC before, MPCC after
    assert after <= 1.2 * np.abs(steady).max()


def test_segment_controller_is_on_the_wire_and_carries_over(tmp_path):
    p = tmp_path / "p.yaml"
    p.write_text(
        f"name: x\nmotor: {MOTOR_A}\nsegments:\n"
        "  - {duration_s: 0.1, speed_rpm: 100}\n"
        "  - {duration_s: 0.1, speed_rpm: 100, current_ctrl: foc}\n"
        "  - {duration_s: 0.1, speed_rpm: 100, current_ctrl: mpcc, capture: true}\n"
    )
    prof = load_profile(str(p))
    bits = gen.ENUMS["segment_flag"]
    assert [s.flags for s in prof.segments] == [
        0,
        bits["cc_foc"],
        bits["cc_mpcc"] | bits["capture"],
    ]


def test_bad_segment_controller_names_the_field(tmp_path):
    p = tmp_path / "p.yaml"
    p.write_text(
        f"name: x\nmotor: {MOTOR_A}\nsegments:\n"
        "  - {duration_s: 0.1, speed_rpm: 100}\n"
        "  - {duration_s: 0.1, speed_rpm: 100, current_ctrl: pid}\n"
    )
    with pytest.raises(ProfileError) as e:
        load_profile(str(p))
    text = str(e.value)
    assert "segments[1].current_ctrl" in text or "segments.1.current_ctrl" in text
    assert "pid" in text
    assert f"{p}:5" in text


def test_firmware_refuses_a_segment_with_both_controllers(tmp_path):
    p = handover_profile(tmp_path, "mpcc", "foc")
    prof = load_profile(str(p))
    link = open_device(DeviceSpec(in_process=True, seed=1), prof)
    try:
        s = Session(link)
        s.hello()
        configure(s, prof)
        bits = gen.ENUMS["segment_flag"]
        with pytest.raises(DeviceError, match="bad_value"):
            s.request(
                "profile_segment",
                index=0,
                duration_s=0.1,
                speed_rpm=100.0,
                ramp_rpm_s=0.0,
                load_nm=0.0,
                flags=bits["cc_foc"] | bits["cc_mpcc"],
                kind=0,
                inject_a=0.0,
                inject_hz=0.0,
            )
    finally:
        link.close()
