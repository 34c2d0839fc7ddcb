"""The current controllers' settings in a profile: a FOC bandwidth the control rate cannot carry
is refused before the run (the firmware refuses it), a setting of a controller no segment runs is
a warning, and keys that are not settings say why."""

from __future__ import annotations

from test_profiles import GOOD, problems_of, write

from pmsm_hil.profiles import load_profile


def test_a_foc_bandwidth_above_half_the_sampling_rate_is_refused_before_the_run(ws):
    path = write("x.yaml", GOOD.replace("  rho: 1.0", "  current_ctrl: foc\n  foc_bw_rad_s: 20000"))
    (msg,) = problems_of(path)
    assert msg == (
        "x.yaml:6: control.foc_bw_rad_s = 20000 is above 0.5/control.ts_s = 10000 rad/s, "
        "the most the control rate 20000 Hz allows (the firmware refuses it); null gives "
        "2 pi/(20 ts_s) = 6283 rad/s"
    )
    path = write("y.yaml", GOOD.replace("  rho: 1.0", "  current_ctrl: foc\n  foc_bw_rad_s: 9000"))
    assert load_profile(path).control.foc_bw_rad_s == 9000


def test_a_setting_of_a_controller_no_segment_runs_is_a_warning(ws):
    path = write("x.yaml", GOOD.replace("  rho: 1.0", "  foc_bw_rad_s: 3000"))
    (w,) = load_profile(path).warnings
    assert w.startswith("x.yaml:5: control.foc_bw_rad_s = 3000 has no effect: no segment runs FOC")
    text = GOOD.replace("  rho: 1.0", "  current_ctrl: foc\n  rho: 2\n  mpcc_candidates: adjacent")
    warnings = load_profile(write("y.yaml", text)).warnings
    assert [w.split(" has no effect")[0] for w in warnings] == [
        "y.yaml:6: control.rho = 2",
        "y.yaml:7: control.mpcc_candidates = adjacent",
    ]
    # a segment that switches to FOC makes the bandwidth count
    text = GOOD.replace("  rho: 1.0", "  foc_bw_rad_s: 3000").replace(
        "speed_rpm: -200}", "speed_rpm: -200, current_ctrl: foc}"
    )
    assert load_profile(write("z.yaml", text)).warnings == []


def test_delay_compensation_and_foc_gains_are_not_settings_and_say_why(ws):
    (msg,) = problems_of(write("x.yaml", GOOD.replace("  rho: 1.0", "  delay_comp: false")))
    assert msg.startswith("x.yaml:5: control.delay_comp = false is not a field of control: ")
    assert "delay compensation is always on" in msg and "dead_time_comp" not in msg
    (msg,) = problems_of(write("y.yaml", GOOD.replace("  rho: 1.0", "  foc_kp: 5")))
    assert "FOC PI gains are designed from control.foc_bw_rad_s" in msg
