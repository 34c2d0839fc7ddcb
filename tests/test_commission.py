"""Commissioning (docs/commissioning.md): each step recovers what is planted in the emulator's
rig within its bound, a miswired rig stops with the right message and the motor off, and the
commissioned motor file is usable by `run --motor`. Seeds 101 and 102: the benchmark
(`pmsm-hil bench commission`) quotes seeds 1..10 only."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from pmsm_hil.cli.main import main as cli_main
from pmsm_hil.commission.score import commission_errors
from pmsm_hil.commission.sequence import commission_profile, run_commission
from pmsm_hil.device import DeviceSpec, open_device
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_motor, load_rig
from pmsm_hil.profiles.shipped import resolve
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions

SEEDS = (101, 102)

# A rig with other planted values than the shipped ones (no saturation: its path is relative)
PLANTED = {
    "name": "planted",
    "effects": {
        "dead_time": {"dead_time_s": 3.5e-6, "v_drop_v": 2.0, "i_dt_a": 0.3},
        "adc_noise": {"i_noise_a": 0.02},
        "adc_quantisation": {"adc_lsb_a": 0.0244140625},
        "encoder": {"lines": 2500, "offset_e_rad": 0.5},
        "friction": {"t_coulomb_nm": 0.05, "b_visc_nms": 2.0e-4},
        "sensor_offset": {"i_a_a": 0.12, "i_b_a": -0.08, "i_c_a": 0.0},
        "sensor_gain": {"i_a_gain": 0.99, "i_b_gain": 1.0, "i_c_gain": 1.015},
        "thermal": {"temp_winding_c": 40.0, "temp_magnet_c": 35.0},
    },
}


def commission(tmp_path, rig_path, seed, steps=None):
    profile = commission_profile(rig_path=rig_path)
    link = open_device(DeviceSpec(in_process=True, seed=seed), profile)
    log = tmp_path / f"commission-{seed}.mcap"
    try:
        res = run_commission(profile, Session(link), log, RunOptions(seed=seed), steps=steps)
    finally:
        link.close()
    return profile, res, log


def check_bounds(profile, res, log):
    assert res.ok, res.failure or res.run.stop_reason
    err = commission_errors(log, res.quantities, profile.rig, profile.control.ts_s)
    for ph in "abc":
        assert abs(err[f"offset_{ph}_a"]) <= 0.005, err
        assert abs(err[f"gain_{ph}"]) <= 0.005, err  # against the gain over the three's mean
    assert abs(err["enc_offset_deg"]) <= 0.2, err
    assert abs(err["plateau_rel"]) <= 0.05, err
    # the plateau split by the clamped-PWM staircase: the dead time's part and the device drop
    assert abs(err["dead_time_rel"]) <= 0.05, err
    assert abs(err["v_drop_v"]) <= 0.25, err
    assert abs(err["r_rel"]) <= 0.02, err
    assert abs(err["l_d_rel"]) <= 0.05, err
    assert abs(err["l_q_rel"]) <= 0.05, err
    assert abs(err["psi_f_rel"]) <= 0.02, err
    return err


@pytest.mark.parametrize("seed", SEEDS)
def test_lab_typical_recovers_planted_values(tmp_path, seed):
    profile, res, log = commission(tmp_path, resolve("lab-typical", "rig"), seed)
    check_bounds(profile, res, log)
    # the steps came in the firmware's order, each reported with its result
    assert [r["step"] for r in res.rows] == [
        "offsets",
        "v_dc",
        "encoder",
        "inverter",
        "r_s",
        "l_dq",
        "psi_f",
    ]
    assert res.run.state == "done"


def test_other_planted_values(tmp_path):
    rig = tmp_path / "planted.yaml"
    rig.write_text(yaml.safe_dump(PLANTED))
    profile, res, log = commission(tmp_path, str(rig), SEEDS[0])
    err = check_bounds(profile, res, log)
    # the gains: relative to their mean, within 0.2 %
    g = [0.99, 1.0, 1.015]
    mean = sum(g) / 3
    for ph, gx in zip("abc", g, strict=False):
        assert res.quantities[f"i_{ph}_gain_err"].value == pytest.approx(gx / mean - 1, abs=2e-3)
    assert res.quantities["i_dt_a"].value == pytest.approx(0.3, rel=0.2)
    assert set(err) >= {"offset_a_a", "enc_offset_deg", "plateau_rel", "r_rel"}


@pytest.mark.parametrize(
    "wiring, step, why, words",
    [
        ({"phases": "acb"}, "encoder", "wrong_direction", "phases are swapped"),
        ({"motor_connected": False}, "encoder", "no_current", "no current flows"),
    ],
)
def test_miswired_rig_stops_with_the_reason(tmp_path, wiring, step, why, words):
    rig = tmp_path / "miswired.yaml"
    rig.write_text(yaml.safe_dump({"name": "miswired", "wiring": wiring}))
    _profile, res, log = commission(tmp_path, str(rig), SEEDS[0])
    assert not res.ok
    assert (res.failed_step, res.failed_why) == (step, why)
    assert words in res.failure
    assert res.run.stop_reason == "commission failed"
    assert res.run.state == "idle"
    # a readable log whose last telemetry has the PWM off (no voltage, currents decayed)
    lg = read_log(str(log))
    assert lg.finalised
    ev = lg.topic("/pmsm/events")
    assert "commission_failed" in list(ev["kind"])
    tr = lg.topic("/sim/truth")
    assert len(tr["t_s"]) > 0


def test_a_wrong_pole_pair_count_is_caught(tmp_path):
    motor = yaml.safe_load(Path(resolve("paper-a-ipmsm", "motor")).read_text())
    motor["pole_pairs"] = 2  # the machine has 4
    motor["torque_max_nm"] = 9.0
    path = tmp_path / "wrong-p.yaml"
    path.write_text(yaml.safe_dump(motor))
    profile = commission_profile(motor_path=str(path), rig_path=resolve("default", "rig"))
    # the real machine (4 pole pairs) on the emulator, the firmware told 2 by the wrong file
    from pmsm_hil.emulator.settings import emulator_settings
    from pmsm_hil.protocol.link import SerialLink
    from pmsm_hil.transport.inproc import InProcessTransport

    settings_motor = load_motor(resolve("paper-a-ipmsm", "motor"))
    link = SerialLink(
        InProcessTransport(emulator_settings(settings_motor, load_rig(resolve("default", "rig"))))
    )
    try:
        res = run_commission(profile, Session(link), tmp_path / "p.mcap", RunOptions())
    finally:
        link.close()
    assert (res.failed_step, res.failed_why) == ("encoder", "pole_pairs")
    assert "pole_pairs" in res.failure


def test_cli_writes_a_motor_file_that_runs(tmp_path, capsys):
    out = tmp_path / "commissioned.yaml"
    code = cli_main(
        [
            "commission",
            "--rig",
            "lab-typical",
            "--seed",
            str(SEEDS[1]),
            "--in-process",
            "-o",
            str(out),
            "--log",
            str(tmp_path / "c.mcap"),
        ]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    for title in ("current-sensor offsets", "encoder offset", "inverter distortion", "psi_f"):
        assert title in text
    m = load_motor(out)
    rec = m.commissioning
    assert rec["nominal"]["r_s_ohm"] == 0.9 and rec["date"].endswith("Z")
    assert rec["measured"]["r_s_ohm"]["spread"] >= 0.0
    assert m.r_s_ohm == pytest.approx(rec["measured"]["r_s_ohm"]["value"])
    assert m.current_sensors is not None and abs(m.current_sensors.i_a_offset_a - 0.05) < 0.005
    assert math.degrees(abs(m.enc_offset_e_rad + 0.021)) < 0.2
    # a run with the commissioned file: the emulator's plant stays the nominal machine
    code = cli_main(
        [
            "run",
            "paper-a",
            "--motor",
            str(out),
            "--rig",
            "lab-typical",
            "--no-live",
            "--stop-after",
            "0.3",
            "--out",
            str(tmp_path / "run.mcap"),
        ]
    )
    assert code in (0, 130), capsys.readouterr()
    tr = read_log(str(tmp_path / "run.mcap")).topic("/sim/truth")
    assert tr["psi_f_wb"][0] == pytest.approx(0.18 * (1 - 0.001 * 20), rel=1e-3)


def test_a_file_commissioned_on_another_rig_is_warned_of(tmp_path, capsys):
    """A motor file commissioned on the emulator's default rig, run on lab-typical: its encoder
    offset and sensor calibration are the default rig's, and the run says so before it starts."""
    out = tmp_path / "c.yaml"
    args = ["commission", "--in-process", "-o", str(out), "--log", str(tmp_path / "c.mcap")]
    assert cli_main(args) == 0
    capsys.readouterr()

    def run(rig):
        run_args = ["run", "paper-a", "--motor", str(out), "--rig", rig, "--no-live"]
        extra = ["--stop-after", "0.05", "--out", str(tmp_path / f"{rig}.mcap")]
        assert cli_main([*run_args, *extra]) in (0, 130)
        return " ".join(capsys.readouterr().err.split())

    err = run("lab-typical")
    assert "warning: " in err and "this run's rig is lab-typical, not default" in err, err
    assert "enc_offset_e_rad, current_sensors" in err and str(out) in err
    assert "commissioning.device" not in run("default")


@pytest.mark.parametrize("stop_s", [2.0, 8.6])  # during the alignment, during the spin
def test_a_host_stop_brakes_and_switches_off(tmp_path, stop_s):
    profile = commission_profile(rig_path=resolve("lab-typical", "rig"))
    link = open_device(DeviceSpec(in_process=True, seed=SEEDS[0]), profile)
    log = tmp_path / "stopped.mcap"
    try:
        res = run_commission(
            profile, Session(link), log, RunOptions(seed=SEEDS[0], stop_after_s=stop_s)
        )
    finally:
        link.close()
    assert not res.ok
    assert res.run.stop_reason == "host stop"
    lg = read_log(str(log))
    assert lg.finalised
    tr = lg.topic("/sim/truth")
    t_stop = float(lg.topic("/pmsm/events")["t_s"][-1])
    assert t_stop < stop_s + 1.0  # braked within a second of the request
    assert abs(tr["speed_rpm"][-1]) < 5.0  # at rest when the PWM went off


@pytest.mark.parametrize("seed", SEEDS)
def test_identification_after_commissioning_holds_on_the_default_rig(tmp_path, seed):
    """NLMS-Adaline with the commissioned motor file, default rig: every parameter within 1 % of
    the plant before the drift step (paper-a-identify's acceptance is 2 %), L_d, L_q, psi_f
    converged within 0.5 s (docs/identification.md)."""
    from pmsm_hil.bench.identify_rigs import _one

    r = _one(
        resolve("paper-a-identify", "profile"), resolve("default", "rig"), seed, tmp_path, True
    )
    cells = r["cells"]
    for q in ("l_d_h", "l_q_h", "psi_f_wb", "r_s_ohm"):
        err, conv = cells[("nlms_adaline", q)]
        assert abs(err) <= 0.01, (q, err)
        if q != "r_s_ohm":
            assert conv is not None and conv <= 0.5, (q, conv)
    for q in ("r_s_ohm", "psi_f_wb"):  # the drift step (R +30 %, psi_f -5 %) tracked within 0.5 s
        assert r["drift_s"][q] is not None and r["drift_s"][q] <= 0.5, (q, r["drift_s"][q])


@pytest.mark.parametrize("seed", SEEDS)
def test_identification_after_commissioning_on_lab_typical(tmp_path, seed):
    """NLMS-Adaline with the commissioned motor file on lab-typical (saturation and
    cross-saturation, the inverter's distortion, iron loss, sensor errors...), against the apparent
    inductances (docs/identification.md). Issue 12's bounds: L_d, L_q, psi_f 1 %, R 2 %, L_q and
    psi_f converged within 0.5 s, the drift step of R and psi_f tracked within 0.5 s."""
    from pmsm_hil.bench.identify_rigs import _one

    r = _one(
        resolve("paper-a-identify", "profile"), resolve("lab-typical", "rig"), seed, tmp_path, True
    )
    cells = r["cells"]
    bounds = {"l_d_h": 0.01, "l_q_h": 0.01, "psi_f_wb": 0.01, "r_s_ohm": 0.02}
    for q, bound in bounds.items():
        err, conv = cells[("nlms_adaline", q)]
        assert abs(err) <= bound, (q, err)
        if q in ("l_q_h", "psi_f_wb"):
            assert conv is not None and conv <= 0.5, (q, conv)
    for q in ("r_s_ohm", "psi_f_wb"):
        assert r["drift_s"][q] is not None and r["drift_s"][q] <= 0.5, (q, r["drift_s"][q])


def test_an_inverter_row_from_before_the_drop_was_measured_reads_as_it_was_written():
    """A log with four values per step (the plateau, band, R, fit rms): no device drop, the motor
    file then keeps its nominal drop."""
    from pmsm_hil.commission.steps import step_quantities

    row = {"step": "inverter", "ref_0": 540.0, "ref_1": 8.0}
    for k, (v, s) in enumerate([(28.5, 0.03), (0.5, 0.0), (1.02, 0.0), (0.06, 0.0)]):
        row[f"value_{k}"], row[f"spread_{k}"] = v, s
    q = step_quantities(row)
    assert "v_drop_v" not in q
    assert q["fit_rms_v"].value == 0.06 and q["v_dist_plateau_v"].value == 28.5
    row.update(value_4=0.07, spread_4=0.0, value_3=1.5, spread_3=0.1, value_5=0.0, spread_5=0.0)
    q = step_quantities(row)
    assert q["v_drop_v"].value == 1.5 and q["fit_rms_v"].value == 0.07


def test_the_measured_dc_link_extremes_do_not_take_the_motor_files_trip_limit_names():
    """The v_dc step's lowest and highest samples were named v_dc_min_v / v_dc_max_v, the motor
    file's trip limits, in the printed and JSON results."""
    from pmsm_hil.commission.steps import step_quantities
    from pmsm_hil.profiles.motor import Motor

    row = {"step": "v_dc"}
    for k, (v, s) in enumerate([(540.2, 0.4), (539.1, 0.0), (541.3, 0.0)]):
        row[f"value_{k}"], row[f"spread_{k}"] = v, s
    q = step_quantities(row)
    assert q["v_dc_v"].value == 540.2
    assert (q["v_dc_lowest_v"].value, q["v_dc_highest_v"].value) == (539.1, 541.3)
    assert set(q) & set(Motor.model_fields) == {"v_dc_v"}  # the mean: the same meaning


def test_a_quantity_shows_its_spread_only_when_the_step_measured_one():
    from pmsm_hil.commission.steps import Measured

    assert Measured(1.02091, 0.0001, "ohm").text() == "1.02091 ohm +- 0.0001"
    assert Measured(540.0, 0.0, "V").text() == "540 V"
    assert Measured(0.971189, 0.0, "").text() == "0.971189"
    assert Measured(-0.02105, 0.02496, "rad").text() == "-1.206 deg (-0.02105 rad) +- 1.430 deg"
    assert Measured(-0.00476, 0.0, "rad").text() == "-0.273 deg (-0.00476 rad)"


def _never_open(*_a, **_k):
    raise AssertionError("the device was opened for a request that should have been refused")


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--i-test", "0"], "--i-test 0: the test current must be in (0, 15] A"),
        (["--i-test", "-3"], "--i-test -3: the test current must be in (0, 15] A"),
        (["--i-test", "100"], "--i-test 100: the test current must be in (0, 15] A"),
        (["--i-test", "nan"], "--i-test nan: the test current must be in (0, 15] A"),
        (["--spin-rpm", "5000"], "--spin-rpm 5000: the spin speed must be in (0, 1500] r/min"),
        (["--spin-rpm", "0"], "to skip the spin, leave psi_f out of the steps"),
        (["--steps", "psi_f"], "step psi_f needs step inverter"),
        (["--steps", "encoder,psi_f"], "step psi_f needs step inverter"),
        (["--steps", "offsets,encoder,psi_f"], "step psi_f needs step inverter"),
        (["--steps", "offsets,r_s"], "step r_s needs step inverter"),
        (["--steps", "encoder,spin"], "unknown commissioning step(s) spin"),
        (["--log", "c.txt"], "--log c.txt: the log is MCAP, name it *.mcap"),
        (["--log", "blocker/c.mcap"], "--log blocker/c.mcap: cannot write there"),
        (["-o", "blocker/m.yaml"], "-o blocker/m.yaml: cannot write there"),
        (["-o", "m.txt"], "-o m.txt: the result is a motor file, name it *.yaml"),
    ],
)
def test_a_bad_request_is_refused_before_anything_runs(tmp_path, monkeypatch, capsys, args, needle):
    """What the firmware would refuse (bad_value, exit 3 after the device was opened), a step
    without the step whose result it needs (a misleading not_repeatable after the spin) and an
    output that cannot be written (a traceback after the sequence): exit 2, the device never
    opened, no log or motor file left behind."""
    import pmsm_hil.device

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(pmsm_hil.device, "open_device", _never_open)
    (tmp_path / "blocker").write_text("a file where a folder is wanted")
    argv = ["commission", "--in-process", "-o", "m.yaml", *args]
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert needle in " ".join(err.split()) and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocker"]


def test_the_request_checks_match_the_firmware(tmp_path):
    """The host's bounds are the firmware's (fw_cmd.c): at the edges the device takes the request
    (a v_dc step, which drives no current), just beyond them it answers bad_value; and a step
    with its prerequisite runs."""
    from pmsm_hil.commission.sequence import RequestError, commission_request
    from pmsm_hil.protocol.session import DeviceError
    from pmsm_hil.runner import run_profile

    profile = commission_profile()
    m = profile.motor

    def send(req):
        link = open_device(DeviceSpec(in_process=True, seed=1), profile)
        try:
            opts = RunOptions(seed=1, requests=[("config_commission", req)])
            return run_profile(profile, Session(link), tmp_path / "edge.mcap", opts)
        finally:
            link.close()

    _, req = commission_request(profile, ["v_dc"], m.i_max_a, m.speed_max_rpm)
    assert send(req).stop_reason == "profile end"
    for field, beyond in (("i_test_a", m.i_max_a * 1.001), ("spin_rpm", m.speed_max_rpm + 1)):
        with pytest.raises(RequestError) as e:
            commission_request(profile, ["v_dc"], **{field: beyond})
        assert e.value.field == field
        with pytest.raises(DeviceError, match="bad_value"):
            send({**req, field: beyond})
    profile, res, _log = commission(tmp_path, None, SEEDS[0], steps=["inverter", "psi_f"])
    assert res.ok, res.failure or res.run.stop_reason
    assert [r["step"] for r in res.rows] == ["inverter", "psi_f"]
    assert abs(res.quantities["psi_f_wb"].value / profile.motor.psi_f_wb - 1) < 0.02


def test_two_commissionings_in_one_second_keep_both_logs(tmp_path, monkeypatch, capsys):
    """The default log is made exclusively, as `run` makes its own: the second gets -2, and
    each motor file names its own run's log."""
    import time

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(time, "strftime", lambda *_a: "20261129-040232")
    for name in ("a.yaml", "b.yaml"):
        assert cli_main(["commission", "--in-process", "--steps", "l_dq", "-o", name]) == 0
    out = capsys.readouterr()
    logs = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert logs == ["commission-20261129-040232-2.mcap", "commission-20261129-040232.mcap"]
    assert load_motor(tmp_path / "a.yaml").commissioning["log"].endswith("040232.mcap")
    assert load_motor(tmp_path / "b.yaml").commissioning["log"].endswith("040232-2.mcap")
    for log in logs:
        assert read_log(str(tmp_path / "runs" / log)).counts["/pmsm/commission"] == 1
    # l_dq drives the motor in the rotor frame: without the encoder step on a motor file whose
    # offset commissioning has not measured, the command says what angle it takes
    assert "without the encoder step, the steps l_dq take the rotor angle" in " ".join(
        out.err.split()
    )
    assert "replaced" not in out.out  # new files
    assert cli_main(["commission", "--in-process", "--steps", "l_dq", "-o", "b.yaml"]) == 0
    assert "motor file: b.yaml" in (text := capsys.readouterr().out)
    assert "it replaced the file that was there" in text  # said, not refused (README: twice)


@pytest.mark.parametrize(
    "there,args",
    [("kept.mcap", []), ("kept-flux-map.mcap", ["--flux-map"]), ("kept.mcap", ["--flux-map"])],
)
def test_a_log_that_is_there_is_kept_as_run_keeps_one(tmp_path, monkeypatch, capsys, there, args):
    """`--log` naming a log that is there (or, with --flux-map, its flux map's log) is refused
    before the device is opened, as `run --out` refuses one: before, it was written over."""
    import pmsm_hil.device

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(pmsm_hil.device, "open_device", _never_open)
    (tmp_path / there).write_bytes(b"an earlier run")
    argv = ["commission", "--in-process", "-o", "m.yaml", "--log", "kept.mcap", *args]
    assert cli_main(argv) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "--log kept.mcap: " in err and "--overwrite replaces it" in err, err
    assert (tmp_path / there).read_bytes() == b"an earlier run"
    assert not (tmp_path / "m.yaml").exists()
    with pytest.raises(AssertionError, match="the device was opened"):  # --overwrite goes on
        cli_main([*argv, "--overwrite"])
