"""Gap diagnosis on emulator records with known (hidden to the diagnoser) rig effects: the probe,
the noise floor, selection, magnitudes, closure, the CLI, and the generator/diagnoser separation."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from gap_records import record_rig

from pmsm_hil.cli.main import main
from pmsm_hil.gap.diagnose import diagnose
from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.noise import floor_from_data, floor_from_spec
from pmsm_hil.gap.probe import Probe
from pmsm_hil.gap.record import load_record
from pmsm_hil.profiles import load_motor, load_rig

ROOT = Path(__file__).resolve().parents[1]
MOTOR = str(ROOT / "profiles/motors/paper-a-ipmsm.yaml")
PROFILE = ROOT / "tests/data/gap-short.yaml"


def _record(tmp, name, effects, sensors=True, seed=7):
    return record_rig(tmp, name, effects, PROFILE, seed, sensors=sensors)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("gapdiag")
    return {
        "ideal": _record(tmp, "ideal", {}, sensors=False),
        "null": _record(tmp, "null", {}),
        "dead_time": _record(
            tmp, "dt", {"dead_time": {"dead_time_s": 1.5e-6, "v_drop_v": 1.0, "i_dt_a": 0.5}}
        ),
        "encoder": _record(tmp, "enc", {"encoder": {"offset_e_rad": 0.04}}),
        "delay": _record(tmp, "delay", {"delay": {"sample_delay_s": 4e-6, "pwm_delay_periods": 1}}),
    }


@pytest.fixture(scope="module")
def motor():
    return MotorModel.from_motor(load_motor(MOTOR))


def test_diagnoser_never_imports_the_generator():
    code = (
        "import sys, pmsm_hil.gap.diagnose, pmsm_hil.gap.csv_import, pmsm_hil.gap.report, "
        "pmsm_hil.gap.rigfile, pmsm_hil.gap.steady\n"
        "bad = [m for m in sys.modules if m.startswith(('pmsm_hil.gapgen', 'pmsm_hil.emulator', "
        "'pmsm_hil.runner', 'pmsm_hil._fw'))]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
    for f in (ROOT / "pmsm_hil/gap").glob("*.py"):
        text = f.read_text()
        assert "gapgen" not in text and "emulator" not in text.replace("emulator's", ""), f.name


def test_rk4_probe_is_exact_on_the_ideal_plant_and_euler_is_not(logs, motor):
    rec = load_record(logs["ideal"])
    p = Probe(rec, motor)
    rk = float(np.mean(p.residual() ** 2))
    eu = float(np.mean(p.residual(euler=True) ** 2))
    assert rk < 1.0  # V^2: what is left is the firmware's float32 and its speed estimate
    assert eu > 5 * rk  # the discretisation gap is reported on its own


def test_noise_floor_from_the_spec_agrees_with_the_data(logs, motor):
    rec = load_record(logs["null"])
    p = Probe(rec, motor)
    spec = float(np.mean(floor_from_spec(p, rec.sensor_spec)))
    data = floor_from_data(p.residual(), p.idx)
    assert spec > 10.0
    assert data == pytest.approx(spec, rel=0.2)
    assert float(np.mean(p.residual() ** 2)) == pytest.approx(spec, rel=0.2)


def test_null_record_selects_nothing(logs, motor):
    from pmsm_hil.gap.report import verdict_lines

    res = diagnose(load_record(logs["null"]), motor)
    assert res["selected"] == []
    assert res["verdict"] == "no structural gap found"
    assert not any(e["selected"] for e in res["effects"])
    assert res["below_threshold"] is None  # nothing the data see under the threshold either
    assert "~ " not in "\n".join(verdict_lines(res))
    res["below_threshold"] = {  # as a record with a warm winding beside a device drop gives it
        "effect": "thermal",
        "gain_v2": 0.113,
        "gain_se_v2": 0.0108,
        "threshold_v2": 0.123,
        "experiment": "record the winding/magnet temperature, or repeat cold",
    }
    text = " ".join(" ".join(verdict_lines(res)).split())
    assert (
        "~ thermal: held-out MSE down 0.113 V^2 (10 standard errors), under the practical " in text
    )
    assert "not named; the data may hold it" in text and "repeat cold" in text
    # as the SEW CM3C80S record with its measured map gives it: refused for its share of what
    # was left
    sliver = dict(gain_v2=0.0626, gain_se_v2=0.0186, threshold_v2=0.458, left_v2=45.81)
    res["below_threshold"] = {**res["below_threshold"], **sliver, "left_rel": 0.005}
    text = " ".join(" ".join(verdict_lines(res)).split())
    assert (
        "~ thermal: held-out MSE down 0.0626 V^2 (3 standard errors), 0.14 % of the 45.8 V^2 "
        "left above the floor (at least 0.5 % asked): not named" in text
    )


def test_the_encoders_half_count_lag_is_the_sensors_not_an_effect(logs, motor, tmp_path):
    """The firmware reads an encoder count as the angle where the count starts: the angle lags
    the rotor by half a count on average. The record knows the counts (the rig's encoder, else
    the default 2500 lines) and the diagnosis takes the lag out; left in, it was fitted as an
    encoder offset of -pi p / counts on every record of the ideal plant. A sealed record (the
    self-test's: no device record, no rig) takes them from its sensor specification."""
    from pmsm_hil.gapgen.recorder import record_profile

    assert load_record(logs["ideal"]).angle_counts == 0  # sealed, no specification: unknown
    assert load_record(logs["null"]).angle_counts == 10000  # sealed, the specification says
    path = tmp_path / "ideal-full.mcap"
    record_profile(PROFILE, path, rig_path=str(ROOT / "profiles/rigs/ideal.yaml"), seed=7)
    rec = load_record(path)
    assert rec.angle_counts == 10000  # the ideal rig names no encoder: the default 2500 lines
    assert rec.angle_lag_e_rad(4) == pytest.approx(np.pi * 4 / 10000)
    assert diagnose(rec, motor)["verdict"] == "no structural gap found"
    rec.angle_counts = 0  # as before: the lag in the data, the model without it
    res = diagnose(rec, motor)
    assert res["selected"] == ["encoder"]
    enc = next(e for e in res["effects"] if e["name"] == "encoder")
    assert enc["magnitude"] == pytest.approx(-np.pi * 4 / 10000, rel=0.2)


def test_dead_time_found_with_its_size_and_closure(logs, motor):
    said: list[str] = []
    res = diagnose(load_record(logs["dead_time"]), motor, progress=said.append)
    assert res["selected"][:1] == ["dead_time"]
    assert res["below_threshold"] is None  # the dead time alone: no other effect hinted at
    # what a long diagnosis's status line shows: each step, every candidate as its fit ends, then
    # the last fits
    step1 = [m for m in said if m.startswith("step 1: ")]
    n_cand = len(step1) - 1
    assert n_cand >= 5 and step1[0] == f"step 1: fitting {n_cand} candidates"
    assert any(m.startswith("step 1: dead_time fitted (") for m in step1)
    assert step1[-1].endswith(f"({n_cand} of {n_cand} candidates)")
    assert any(m.startswith("step 2: dead_time + ") for m in said)
    assert said.index(next(m for m in said if m.startswith("final fit: dead_time"))) > n_cand
    e = res["effects"][0]
    assert e["name"] == "dead_time" and e["selected"]
    assert e["magnitude"] == pytest.approx(1.5e-6, rel=0.15)
    assert e["interval"][0] <= 1.5e-6 * 1.15 and e["interval"][1] >= 1.5e-6 * 0.85
    assert res["closure"]["closure"] > 0.8
    assert res["discretisation_gap"]["excess_v2"] > 0


def test_the_same_diagnosis_with_fits_side_by_side(logs, motor):
    """--workers 2 runs the candidate fits of each step in two processes: the diagnosis is the same,
    bit for bit, as in one (every fit runs with one BLAS thread, wherever it runs)."""
    rec = load_record(logs["delay"])
    one = diagnose(rec, motor, workers=1)
    two = diagnose(rec, motor, workers=2)
    assert one["selected"][:1] == ["delay"]
    assert json.dumps(two, sort_keys=True) == json.dumps(one, sort_keys=True)


def test_encoder_offset_found(logs, motor):
    res = diagnose(load_record(logs["encoder"]), motor)
    assert res["selected"][:1] == ["encoder"]
    assert res["effects"][0]["magnitude"] == pytest.approx(0.04, rel=0.2)


def test_delay_quoted_as_the_total_delay(logs, motor, tmp_path):
    """The total delay (4 us sample delay + one period of PWM delay) with an interval that holds
    it, and `gap augment`'s rig file carries the same total as the diagnosis quotes."""
    from pmsm_hil.gap.rigfile import fitted_rig

    res = diagnose(load_record(logs["delay"]), motor)
    assert res["selected"][:1] == ["delay"]
    e = res["effects"][0]
    assert e["quantity"] == "total_delay_s"
    assert e["magnitude"] == pytest.approx(54e-6, rel=0.15)
    assert e["parameters"]["pwm_delay_periods"] == pytest.approx(1.0, abs=0.2)
    lo, hi = e["interval"]
    assert 0 < lo <= 54e-6 <= hi
    fitted_rig(res, motor, tmp_path / "rig.yaml")
    d = load_rig(tmp_path / "rig.yaml").effects.delay
    assert d.sample_delay_s + d.pwm_delay_periods * res["ts_s"] == pytest.approx(
        e["magnitude"], rel=1e-9
    )


def test_cli_json_report_and_augment(logs, tmp_path, capsys):
    assert main(["gap", str(logs["dead_time"]), "--motor", MOTOR, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    names = [e["name"] for e in out["effects"]]
    assert names[0] == "dead_time" and out["effects"][0]["selected"]
    assert set(names) >= {
        "dead_time",
        "delay",
        "encoder",
        "sensor_offset",
        "sensor_gain",
        "saturation",
        "thermal",
        "flux_harmonics",
        "dc_link",
        "iron_loss",
        "friction",
        "cogging",
    }
    for k in ("name", "selected", "magnitude", "interval", "closure", "evidence"):
        assert k in out["effects"][0]
    assert "base_gap" in out and "discretisation_gap" in out and "closure" in out
    rep = ["gap", str(logs["dead_time"]), "--motor", MOTOR, "--report", str(tmp_path / "rep")]
    assert main([*rep, "--workers", "1"]) == 0
    text = capsys.readouterr().out
    # the last line: how long it took, on how many processes
    assert re.search(r"\ndiagnosed in \d+ s with 1 fit process\n$", text), text[-200:]
    assert (
        "dead_time" in text
        and (tmp_path / "rep/index.html").exists()
        and (tmp_path / "rep/gap.json").exists()
    )
    # the effects not selected: their fitted-alone magnitudes greyed and marked, not findings
    page = (tmp_path / "rep/index.html").read_text()
    n_other = sum(1 for e in out["effects"] if not e["selected"])
    assert n_other and page.count(" (alone)</span>") == n_other
    assert "what it reached fitted alone" in page
    # the report has the fitted rig beside it (one diagnosis, not a second by `gap augment`)
    assert "fitted-rig.yaml" in text and "gap verify" in text
    in_report = load_rig(tmp_path / "rep" / "fitted-rig.yaml")
    rig_path = tmp_path / "fitted-rig.yaml"
    assert (
        main(["gap", "augment", str(logs["dead_time"]), "--motor", MOTOR, "-o", str(rig_path)]) == 0
    )
    rig = load_rig(rig_path)
    assert in_report.effects.dead_time.dead_time_s == rig.effects.dead_time.dead_time_s
    assert rig.effects.dead_time.enabled
    assert rig.effects.dead_time.dead_time_s == pytest.approx(1.5e-6, rel=0.15)
    assert rig.effects.adc_noise.i_noise_a == pytest.approx(0.02)


def test_cli_errors(tmp_path, capsys):
    assert main(["gap", str(tmp_path / "nope.mcap"), "--motor", MOTOR]) == 2
    assert "no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap")
    assert main(["gap", str(bad), "--motor", MOTOR]) == 2
    assert "Traceback" not in capsys.readouterr().err
    folder = tmp_path / "adir"
    folder.mkdir()
    cases = [  # what a user types, and what it must say (exit 2, no traceback)
        (["gap", str(folder)], f"{folder}: is a directory, not a log"),
        (["gap", str(bad), "--holdout", str(tmp_path / "no.mcap")], "--holdout"),
        (["gap", str(bad), "--report", str(bad)], f"--report {bad}: is a file"),
        (["gap", str(bad), "--workers", "-2"], "--workers = -2 must be >= 1"),
        (["gap", "selftest", "--trials", "0"], "--trials = 0 must be >= 1"),
        (["gap", "record", "diagnose", "-o", str(folder)], f"-o {folder}: is a directory"),
        (["gap", "augment", str(bad), "-o", str(folder)], f"-o {folder}: is a directory"),
        (["gap", "verify", str(folder), "--rig", "ideal"], "is a directory, not a log"),
        (["gap", "augmnet", str(bad), "-o", "f.yaml"], "did you mean `gap augment`?"),
        (
            ["gap", "record", "paper-b", "-o", str(tmp_path / "pb.mcap")],
            "paper-b: current_ctrl: foc throughout",  # refused before the run, not after it
        ),
        (["gap", str(bad), "--rig", "lab-typical"], "--rig is for `gap record` and `gap verify`"),
        (
            ["gap", str(bad), "--motor", str(ROOT / "profiles/diagnose.yaml")],
            "diagnose.yaml: is a profile (it has segments), not a motor file",
        ),
        (
            ["gap", str(bad), "--motor", str(ROOT / "profiles/rigs/lab-typical.yaml")],
            "lab-typical.yaml: is a rig file (it has effects), not a motor file",
        ),
    ]
    for argv, says in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err, (argv, err)
    assert not (tmp_path / "adir" / "record.mcap").exists()
    assert not (tmp_path / "pb.mcap").exists()


def test_outputs_that_cannot_be_written_are_refused_before_the_work(logs, tmp_path, capsys):
    """-o and --report of every gap command are checked before a record, a diagnosis or a
    self-test runs: exit 2 naming the option, not a traceback after the work."""
    log = str(logs["ideal"])
    afile = tmp_path / "afile"
    afile.write_text("x")
    cases = [
        (
            ["gap", "record", "diagnose", "-o", f"{afile}/x.mcap"],
            f"{afile} is a file, not a folder",
        ),
        (["gap", "augment", log, "-o", f"{afile}/x.yaml"], f"{afile} is a file, not a folder"),
        (["gap", log, "--report", f"{afile}/rep"], f"--report {afile}/rep: cannot make the folder"),
        (["gap", "selftest", "--trials", "1", "-o", str(afile)], f"-o {afile}: is a file"),
    ]
    if os.path.isdir("/proc/self"):  # a folder nobody can make files in, not even root
        cases += [
            (["gap", "record", "diagnose", "-o", "/proc/x.mcap"], "-o /proc/x.mcap: cannot write"),
            (["gap", "augment", log, "-o", "/proc/x.yaml"], "-o /proc/x.yaml: cannot write"),
            (["gap", log, "--report", "/proc/gap"], "--report /proc/gap: cannot make the folder"),
            (["gap", "selftest", "--trials", "1", "-o", "/proc/j"], "-o /proc/j: cannot make"),
        ]
    for argv, says in cases:
        assert main(argv) == 2, argv
        out = capsys.readouterr()
        assert says in out.err and "Traceback" not in out.err, (argv, out.err)
        assert "gap:" not in out.out and "labels sealed" not in out.out, argv  # nothing ran
    ok = tmp_path / "ok.yaml"  # a writable -o is left as it was: no file made by the check
    assert main(["gap", "augment", log, "-o", str(ok)]) == 0 and ok.exists()


def _log_with(profile_yaml: str | None, truncated: bool = False):
    from types import SimpleNamespace

    att = SimpleNamespace(data=profile_yaml.encode()) if profile_yaml is not None else None
    return SimpleNamespace(
        attachment=lambda name: att if name == "profile.yaml" else None,
        truncated=truncated,
        finalised=not truncated,
    )


def test_a_modulator_run_is_refused_and_an_estimated_angle_noted(logs):
    """A FOC/SVPWM run's record holds switch states sampled once a period, not the voltage over
    it: refused (a confident diagnosis of nonsense before: a 255 us delay, -80 K). A run on an
    estimated angle, or a file cut short, is diagnosed with a note."""
    from pmsm_hil.gap.record import _log_notes, _modulator_problem

    rec = load_record(logs["null"])
    foc = "control:\n  current_ctrl: foc\n  angle_src: mras\n"
    why = _modulator_problem(_log_with(foc), "pb.mcap", rec)
    assert why and why.startswith("pb.mcap: the run used current_ctrl: foc (a PWM modulator)")
    mixed = foc + "segments:\n  - {name: a, current_ctrl: mpcc}\n"
    assert _modulator_problem(_log_with(mixed), "x", rec) is None  # some periods are FCS
    assert _modulator_problem(_log_with("control: {ts_s: 5.0e-5}\n"), "x", rec) is None
    assert _modulator_problem(_log_with(None), "x", rec) is None  # no profile: a CSV import
    notes = _log_notes(_log_with(foc, truncated=True), "pb.mcap")
    assert notes[0].startswith("pb.mcap is not finalised")
    assert "angle_src: mras" in notes[1] and "encoder offset" in notes[1]
    assert _log_notes(_log_with(None), "x") == []


def test_augment_writes_the_total_delay_the_diagnosis_quotes(tmp_path, motor):
    """A rig's PWM update is late by whole periods: the fitted fraction of a period moves to the
    sample delay (the one-step residual cannot tell the two apart), so the rig's total delay is
    the diagnosis's, and the file says what moved. The first case is a lab-typical record's fit
    (1.51 us quoted, 3e-13 s of sample delay and 0.03 periods of PWM delay: the rig file had
    `sample_delay_s: 2.99e-13` and no PWM delay, the delay dropped without a word)."""
    from pmsm_hil.gap.effects import EFFECTS, primary_value
    from pmsm_hil.gap.rigfile import fitted_rig

    ts_s = 50e-6

    def written(sample_s: float, periods: float) -> tuple[dict, str, float]:
        res = {
            "ts_s": ts_s,
            "effects": [
                {
                    "name": "delay",
                    "selected": True,
                    "parameters": {"sample_delay_s": sample_s, "pwm_delay_periods": periods},
                }
            ],
        }
        path = tmp_path / f"rig-{sample_s}-{periods}.yaml"
        fitted_rig(res, motor, path)
        load_rig(str(path))  # a rig file the loader takes
        text = path.read_text()
        quoted = primary_value(EFFECTS["delay"], np.array([sample_s, periods]), motor, ts_s)
        return yaml.safe_load(text)["effects"]["delay"], text, quoted

    for sample_s, periods, whole in (
        (2.9885408599357397e-13, 0.030237141121022725, 0),
        (2e-6, 0.43, 0),
        (2e-6, 1.6, 1),
        (0.0, 0.97, 0),  # rounded up, the sample delay would be negative
    ):
        d, text, quoted = written(sample_s, periods)
        assert d["pwm_delay_periods"] == whole
        assert d["sample_delay_s"] >= 0
        assert d["sample_delay_s"] + whole * ts_s == pytest.approx(quoted, rel=1e-9)
        assert (
            f"# delay: the fitted PWM delay of {periods:.3f} periods is written as {whole}" in text
        )
    d, text, _ = written(5e-6, 1.0)  # whole periods: nothing moves, nothing said
    assert d == {"sample_delay_s": 5e-6, "pwm_delay_periods": 1} and "# delay:" not in text


def test_total_delay_interval_takes_the_parameters_correlation():
    """The lab-typical record's final fit: sample and PWM delay correlate at -0.99; their bounds
    moved together gave [-1.47, 4.49] us about 1.51 us; the covariance gives an interval that
    excludes zero (and is at least the model-form term wide)."""
    from pmsm_hil.gap.diagnose import MODEL_FORM_REL, total_delay_interval

    cov = np.array([[5.692e-13, -1.12689e-8], [-1.12689e-8, 2.25348e-4]])
    lo, hi = total_delay_interval(1.5119e-6, cov, 50e-6)
    assert 1.1e-6 < lo < 1.3e-6 and 1.7e-6 < hi < 1.9e-6
    assert hi - lo >= 2 * 1.96 * MODEL_FORM_REL * 1.5119e-6
    # uncorrelated, the same standard errors: the interval is wide and is cut at zero
    lo, hi = total_delay_interval(1.5119e-6, np.diag(np.diag(cov)), 50e-6)
    assert lo == 0.0 and hi > 3e-6


@pytest.mark.parametrize("a", [0.04, 0.2, 0.45, 0.6, 0.8])
def test_the_probe_inverts_a_sample_delays_blend_exactly(logs, motor, a):
    """Samples taken a fraction a of a period early blend two boundary currents, meas(k) =
    (1 - a) i(k) + a i(k - 1); the probe recovers i(k) along each run (forward below a = 1/2,
    backward above), to rounding: putting meas(k - 1) for i(k - 1) left a^2 / (1 - a) of the
    previous increment (0.15 A here at a = 0.2), which doubled the residual at the true delay."""
    probe = Probe(load_record(logs["null"]), motor)
    rng = np.random.default_rng(3)
    n = len(probe.rec.i_abc)
    i = np.cumsum(rng.normal(0.0, 1.0, (n, 2)), axis=0)
    meas = np.empty_like(i)
    for r0, r1 in probe.rec.runs:  # a run starts (a < 1/2) or ends (above) on a steady current
        if a < 0.5:
            i[r0] = i[r0 + 1] if r1 - r0 > 1 else i[r0]
            prev = np.vstack([i[r0 : r0 + 1], i[r0 : r1 - 1]])
        else:
            i[r1 - 1] = i[r1 - 2] if r1 - r0 > 1 else i[r1 - 1]
            prev = np.vstack([i[r0 : r0 + 1], i[r0 : r1 - 1]])
        meas[r0:r1] = (1 - a) * i[r0:r1] + a * prev
    got = probe._unblended(meas, a)
    inner = np.concatenate([np.arange(r0 + 1, r1 - 1) for r0, r1 in probe.rec.runs])
    err = np.max(np.abs(got[inner] - i[inner]))
    assert err < 1e-6 * np.max(np.abs(i))
    old = (meas[inner] - a * meas[inner - 1]) / (1 - a)
    assert np.max(np.abs(old - i[inner])) > 1e3 * err  # what the approximation left


def test_a_pwm_delay_is_fitted_in_whole_periods_and_leaves_no_iron_loss(tmp_path, motor):
    """An 8 us sample delay beside two periods of PWM delay (a self-test trial, seed 61): the
    continuous fit took it as 0.156 periods of PWM delay, which left a d-voltage even in speed on
    the settled plateaus (0.24 V rms), and the diagnosis answered `delay, iron_loss` (1450 ohm).
    With the PWM delay in whole periods and the sample delay's blend inverted exactly, the delay
    alone, its two parts where they are, and the plateaus flat."""
    log = _record(
        tmp_path, "delay8", {"delay": {"sample_delay_s": 8e-6, "pwm_delay_periods": 2}}, seed=11
    )
    res = diagnose(load_record(log), motor)
    assert res["selected"] == ["delay"]
    e = res["effects"][0]
    assert e["parameters"]["pwm_delay_periods"] == 2.0
    assert e["parameters"]["sample_delay_s"] == pytest.approx(8e-6, rel=0.05)
    assert e["magnitude"] == pytest.approx(108e-6, rel=0.005)
    assert max(res["plateaus"].get("rms_before_v", [0.0])) < 0.05
    assert not [x["name"] for x in res["effects"] if x["selected"] and x["name"] != "delay"]


def test_a_floor_the_data_cannot_give_is_said_to_be_none_not_zero():
    """The lag-1 estimate of the noise floor is clipped at zero when the residual left is
    correlated from period to period (an effect outside the library): the verdict says the floor
    could not be estimated instead of quoting 0 V rms as a floor."""
    from pmsm_hil.gap.report import verdict_lines

    res = {
        "verdict": "unexplained residual",
        "base_gap": {"rms_v": 12.0},
        "discretisation_gap": {"excess_v2": 25.0, "mse_euler_v2": 169.0, "mse_rk4_v2": 144.0},
        "noise_floor_v2": 0.0,
        "noise_floor_source": "estimated from the data (lag-1 autocovariance of the residual)",
        "selected": [],
        "closure": {},
        "effects": [],
        "parametric_gap": {
            "r_s_ohm": 1.0,
            "l_d_h": 5e-3,
            "l_q_h": 12e-3,
            "psi_f_wb": 0.18,
            "closure": 0.1,
        },
    }
    text = "\n".join(verdict_lines(res))
    assert "noise floor not estimable from the data" in text and "0 V rms" not in text
    assert "discretisation gap (Euler vs RK4) +1 V rms (25 V^2)" in text  # 13 against 12 V rms
    res["noise_floor_v2"] = 40.0
    assert "noise floor 6.32 V rms (estimated from the data" in "\n".join(verdict_lines(res))
    res.update(noise_floor_v2=0.0, noise_floor_source="sensor specification")
    assert "noise floor 0 V rms (sensor specification)" in "\n".join(verdict_lines(res))


def test_a_clear_gain_under_the_practical_threshold_is_said_not_named():
    """The candidate the selection stopped at is reported when the data see it (gain above three
    standard errors) though under the practical threshold: a warm winding whose R rise the dead
    time's device drop took (a walk's rig: +55 K read as v_drop 2.79 V against 2.0 V, thermal's
    gain 0.113 V^2 at 10 standard errors under a threshold of 0.123 V^2). A gain within its
    noise, or a selection that ended on an accepted step, says nothing."""
    from pmsm_hil.gap.diagnose import LEFT_REL, PRACTICAL_REL, below_threshold

    def step(effect, g, se, thr, left=None, floor=None):
        # the practical threshold (0.3 % of the floor) bound, and nothing left beyond it, unless
        # given: what was left before the step and its floor
        floor = thr / PRACTICAL_REL if floor is None else floor
        return {
            "effect": effect,
            "gain_v2": g,
            "gain_se_v2": se,
            "threshold_v2": thr,
            "accepted": g > thr,
            "residual_v2": floor if left is None else left,
            "floor_v2": floor,
        }

    chosen = ["dead_time"]
    seen = below_threshold(
        [step("dead_time", 45.7, 1.2, 3.6), step("thermal", 0.113, 0.0108, 0.123)], chosen
    )
    assert seen is not None and seen["effect"] == "thermal"
    assert (
        below_threshold(
            [step("dead_time", 45.7, 1.2, 3.6), step("thermal", 0.02, 0.0108, 0.123)], chosen
        )
        is None
    )
    assert below_threshold([step("dead_time", 45.7, 1.2, 3.6)], chosen) is None  # the cap reached
    # statistically clear but a tenth of the threshold (the dead-time rig's thermal: model form)
    tiny = step("thermal", 9.2e-5, 1.5e-5, 8.6e-4)
    assert below_threshold([step("dead_time", 45.7, 1.2, 3.6), tiny], chosen) is None
    # a third of the threshold but 3.2 standard errors (a record with cogging and EMF harmonics
    # stopping at saturation, which it does not have)
    loose = step("saturation", 0.043, 0.0135, 0.123)
    assert below_threshold([step("delay", 45.7, 1.2, 3.6), loose], ["delay"]) is None
    assert below_threshold([], []) is None
    # clear, over the practical threshold, and refused only for taking 0.14 % of what was left
    # (a SEW CM3C80S record: its measured map's misfit, 45.8 V^2 above the floor, after
    # saturation, dead time and encoder): said, with what was left
    chosen = ["saturation", "dead_time", "encoder"]
    sliver = step("thermal", 0.0626, 0.0186, LEFT_REL * 45.811, left=46.974, floor=1.163)
    seen = below_threshold([step("saturation", 458.5, 51.7, 155.0), sliver], chosen)
    assert seen is not None and seen["effect"] == "thermal"
    assert seen["left_v2"] == pytest.approx(45.811)
    # the same gain within three of its standard errors: nothing said
    assert (
        below_threshold(
            [step("saturation", 458.5, 51.7, 155.0), {**sliver, "gain_se_v2": 0.03}], chosen
        )
        is None
    )


def test_a_fitted_saturation_map_holds_its_inductances_beyond_the_records_currents(tmp_path):
    """The SEW rig's fitted saturation (its cross term extrapolated beyond the record's i_d of
    -1.9..0.5 A): d psi_q / d i_q went negative at i_d = -5 A, i_q = 14 A, the map written on
    the grid of +-1.25 i_max could not be inverted and the fitted rig's re-run tripped over_current
    when its load came on (`gap verify` closure -91). Followed only over the record's currents,
    the map rises with each current everywhere and the rig loader takes it; the same fit written
    as before is refused by the loader, naming the cell."""
    from pmsm_hil.gap.model import MotorModel
    from pmsm_hil.gap.rigfile import fitted_rig
    from pmsm_hil.profiles import load_motor
    from pmsm_hil.profiles.fluxmap import FluxMapError, load_flux_map
    from pmsm_hil.profiles.shipped import resolve

    sew = MotorModel.from_motor(load_motor(resolve("sew-cm3c80s", "motor")))
    fit = {"k_d": 0.267, "i_sd_a": 8.13, "k_q": 0.617, "i_sq_a": 2.29, "k_x": 0.524, "k_c": 0.0092}
    res = {
        "ts_s": 50e-6,
        "effects": [{"name": "saturation", "selected": True, "parameters": fit}],
        "current_range_a": {"i_d_a": [-1.85, 0.51], "i_q_a": [-7.02, 15.05]},
    }
    fitted_rig(res, sew, tmp_path / "rig.yaml")
    fm = load_flux_map(str(tmp_path / "rig-map.csv"))
    assert np.all(np.diff(fm.psi_d_wb, axis=1) > 0) and np.all(np.diff(fm.psi_q_wb, axis=0) > 0)
    load_rig(str(tmp_path / "rig.yaml"))
    del res["current_range_a"]  # the model followed over the whole grid, as before
    fitted_rig(res, sew, tmp_path / "old.yaml")
    with pytest.raises(FluxMapError, match="does not rise with"):
        load_flux_map(str(tmp_path / "old-map.csv"))
