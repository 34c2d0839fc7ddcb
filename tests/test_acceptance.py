"""Acceptance criteria in profiles and `pmsm-hil test`: validation, no effect on the device, the
pass/fail table, JUnit XML, the exit code."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
from emu_helpers import DEVICE_TOPICS, raw_messages, run_inproc

from pmsm_hil.profiles import ProfileError, load_profile

CLI = [sys.executable, "-m", "pmsm_hil.cli.main"]


def with_acceptance(tmp_path, data, text: str, name: str = "p.yaml"):
    """tests/data/short.yaml with an acceptance section (motor and rig paths made absolute)."""
    src = (data / "short.yaml").read_text()
    src = src.replace("../../profiles/", str(data.parent.parent / "profiles") + "/")
    p = tmp_path / name
    p.write_text(src + text)
    return p


@pytest.mark.parametrize(
    "text, field, message",
    [
        (
            "acceptance:\n  run:\n    speed_error_max_rpm: wide\n",
            "acceptance.run.speed_error_max_rpm",
            "'wide'",
        ),
        ("acceptance:\n  run:\n    faults: never\n", "acceptance.run.faults", "is not one of"),
        (
            "acceptance:\n  run:\n    recovery_max_s: -1\n",
            "acceptance.run.recovery_max_s",
            "must be > 0",
        ),
        (
            'acceptance:\n  segments:\n    - {segment: "lod on", recovery_max_s: 0.3}\n',
            "acceptance.segments[0].segment",
            "did you mean 'load on'",
        ),
        (
            "acceptance:\n  segments:\n    - {segment: 7, recovery_max_s: 0.3}\n",
            "acceptance.segments[0].segment",
            "is not a segment index",
        ),
        (
            "acceptance:\n  segments:\n    - {segment: 1}\n",
            "acceptance.segments[0]",
            "gives no bound",
        ),
        (
            "acceptance:\n  run:\n    identification:\n      - {estimator: nlms, param: l_q_h, error_max_rel: 0.02}\n",
            "acceptance.run.identification[0].estimator",
            "is not one of",
        ),
        (
            "acceptance:\n  run:\n    angle_error_rms_max_rad: 0\n",
            "acceptance.run.angle_error_rms_max_rad",
            "is outside the allowed range (0, 3.2] rad",
        ),
        (
            "acceptance:\n  run:\n    recovery_max: 0.3\n",
            "acceptance.run.recovery_max",
            "did you mean 'recovery_max_s'",
        ),
    ],
)
def test_acceptance_errors_name_file_line_field(tmp_path, data, text, field, message):
    p = with_acceptance(tmp_path, data, text)
    n_lines = len((data / "short.yaml").read_text().splitlines())
    with pytest.raises(ProfileError) as e:
        load_profile(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}:"), msg
    line = int(msg.split(":")[1])
    assert line > n_lines  # on a line of the acceptance section
    assert f" {field}" in msg and message in msg, msg


def test_shipped_profiles_load_with_their_criteria(root):
    a = load_profile(root / "profiles" / "paper-a.yaml")
    assert a.acceptance.run.speed_error_max_rpm == "band" and a.acceptance.run.recovery_max_s == 0.3
    ident = load_profile(root / "profiles" / "paper-a-identify.yaml")
    assert {b.param for b in ident.acceptance.run.identification} == {
        "l_d_h",
        "l_q_h",
        "psi_f_wb",
        "r_s_ohm",
    }
    assert load_profile(root / "profiles" / "sew-cm3c80s.yaml").acceptance is None


def test_criteria_change_nothing_on_the_device(tmp_path, data):
    p = with_acceptance(
        tmp_path, data, "acceptance:\n  run: {faults: forbidden, recovery_max_s: 0.3}\n"
    )
    run_inproc(data / "short.yaml", tmp_path / "a.mcap", seed=4)
    run_inproc(p, tmp_path / "b.mcap", seed=4)
    a, b = raw_messages(tmp_path / "a.mcap"), raw_messages(tmp_path / "b.mcap", DEVICE_TOPICS)
    assert len(a) > 5000 and a == b


def test_test_passes_and_writes_junit(tmp_path, data):
    p = with_acceptance(
        tmp_path,
        data,
        "acceptance:\n  run:\n    faults: forbidden\n    "
        "speed_error_max_rpm: band\n    recovery_max_s: 0.3\n",
    )
    junit = tmp_path / "out.xml"
    r = subprocess.run(
        [*CLI, "test", str(p), "--junit", str(junit)], capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "PASS short" in r.stdout and "1 of 1 profiles passed" in r.stdout
    suite = ET.parse(junit).getroot().find("testsuite")
    # complete, faults, speed error on 3 plateaus, recovery on 2 load steps
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("7", "0", "0")


def test_test_fails_with_the_measured_value_beside_the_bound(tmp_path, data):
    failing = with_acceptance(
        tmp_path,
        data,
        'acceptance:\n  segments:\n    - {segment: "load on", '
        "recovery_max_s: 0.001, ripple_q_max_a: 100}\n",
        "f.yaml",
    )
    passing = with_acceptance(tmp_path, data, "acceptance:\n  run: {faults: forbidden}\n", "g.yaml")
    junit = tmp_path / "out.xml"
    r = subprocess.run(
        [
            *CLI,
            "test",
            str(failing),
            str(passing),
            "--junit",
            str(junit),
            "--workers",
            "1",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 1, r.stdout + r.stderr
    assert "FAIL short: 2 of 3 checks passed" in r.stdout
    assert "PASS short: 2 of 2 checks passed" in r.stdout
    assert "1 of 2 profiles passed" in r.stdout
    line = next(x for x in r.stdout.splitlines() if "recovery" in x)
    assert "<= 0.001 s" in line and "FAIL" in line
    suites = ET.parse(junit).getroot().findall("testsuite")
    assert [s.get("failures") for s in suites] == ["1", "0"]
    failure = suites[0].find("testcase/failure")
    assert "bound <= 0.001 s" in failure.get("message") and "measured 0.0" in failure.get("message")
    assert (tmp_path / "o" / "results.parquet").is_file()


def test_test_reports_a_bad_profile_without_traceback(tmp_path, data):
    p = with_acceptance(tmp_path, data, "acceptance:\n  run: {faults: sometimes}\n")
    junit = tmp_path / "out.xml"
    r = subprocess.run(
        [*CLI, "test", str(p), "--junit", str(junit)], capture_output=True, text=True, timeout=120
    )
    assert r.returncode == 2 and "acceptance.run.faults = 'sometimes'" in r.stderr
    assert "Traceback" not in r.stderr
    # CI finds a report that says why, not none
    suite = ET.parse(junit).getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("errors")) == ("1", "1")
    error = suite.find("testcase/error")
    assert suite.find("testcase").get("name") == "inputs"
    assert "acceptance.run.faults = 'sometimes'" in error.get("message")


def test_angle_error_bounds_judge_the_estimator_closing_the_loop():
    """The run's angle-estimate bounds take the run summary's estimator figures; without an
    estimator closing the loop they fail as not measured, never pass by default."""
    from types import SimpleNamespace

    from pmsm_hil.analysis.acceptance import evaluate
    from pmsm_hil.profiles.acceptance import Acceptance

    acc = Acceptance.model_validate(
        {"run": {"angle_error_rms_max_rad": 0.02, "angle_error_max_rad": 0.1}}
    )

    def summary(est):
        return SimpleNamespace(complete=True, ended=None, faults=[], segments=[], estimator=est)

    est = {"theta_err_rms_rad": 0.0061, "theta_err_max_rad": 0.13}
    checks = {c.criterion: c for c in evaluate(acc, summary(est))}
    assert checks["angle error RMS"].passed and checks["angle error RMS"].measured == "0.0061 rad"
    assert not checks["largest angle error"].passed
    assert checks["largest angle error"].bound == "<= 0.1 rad"
    none = {c.criterion: c for c in evaluate(acc, summary(None))}
    assert not none["angle error RMS"].passed and "not measured" in none["angle error RMS"].measured


def test_run_ends_with_the_profiles_acceptance_and_names_what_it_missed(tmp_path, data):
    """`pmsm-hil run` of a profile with criteria prints how many passed and, for a failed one, the
    measured value beside the bound (the same checks as `pmsm-hil test`)."""
    p = with_acceptance(
        tmp_path,
        data,
        'acceptance:\n  run: {faults: forbidden}\n  segments:\n    - {segment: "load on", '
        "recovery_max_s: 0.001}\n",
    )
    r = subprocess.run(
        [*CLI, "run", str(p), "--no-live", "--out", str(tmp_path / "r.mcap")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr  # criteria judge; they do not fail a run
    line = next(x for x in r.stdout.splitlines() if x.startswith("acceptance"))
    assert "2 of 3 checks passed" in line
    assert "segment 1 'load on' recovery" in line and "(<= 0.001 s)" in line


def test_a_missed_plateau_bound_is_named_in_the_verdict():
    from pmsm_hil.analysis.summary import RunSummary, SegmentStats, verdict_text

    def seg(i, name, mean, band, rec):
        return SegmentStats(
            index=i,
            name=name,
            t_start_s=0.0,
            t_end_s=1.0,
            setpoint_rpm=15.0,
            load_nm=0.0,
            load_step_nm=0.0,
            band_rpm=band,
            mean_error_rpm=mean,
            mean_ok=abs(mean) <= band,
            true_mean_error_rpm=None,
            recovery_s=rec,
            recovery_ok=None if rec is None else rec <= 0.3,
            ripple_d_a=0.1,
            ripple_q_a=0.1,
            faults=0,
        )

    s = RunSummary(path="x", ended="profile end", expected=["a", "b", "c"])
    s.segments = [seg(0, "a", 0.1, 1.0, None), seg(1, "b", 2.5, 1.0, 0.05), seg(2, "c", 0, 1, 1.5)]
    v = verdict_text(s)
    assert "bounds missed" in v and "segment 0" not in v
    assert "segment 1 'b' mean speed error +2.50 r/min beyond ±1" in v
    assert "segment 2 'c' recovery 1.50 s > 0.3 s" in v


def test_test_hints_at_commissioning_when_identification_fails_on_an_uncommissioned_rig():
    """paper-a-identify on lab-typical with the motor file as shipped misses its identification
    bounds (the rig's encoder offset, inverter): the verdict says why and what to run; on the
    default rig (no effects) there is no such hint."""
    r = subprocess.run(
        [*CLI, "test", "paper-a-identify", "--rig", "lab-typical"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 1, r.stdout + r.stderr
    out = " ".join(r.stdout.split())
    assert "hint: the motor file is not commissioned" in out
    assert "pmsm-hil commission --rig lab-typical" in out and "--motor" in out
    from pmsm_hil.analysis.acceptance import commission_hint
    from pmsm_hil.profiles.shipped import resolve

    def text(name: str, kind: str) -> str:
        with open(resolve(name, kind), encoding="utf-8") as f:
            return f.read()

    motor, lab, default = (
        text("paper-a-ipmsm", "motor"),
        text("lab-typical", "rig"),
        text("default", "rig"),
    )
    failed = ["nlms_adaline l_q_h error"]
    assert "encoder offset" in (commission_hint(failed, motor, lab) or "")
    assert commission_hint(failed, motor, default) is None  # the firmware's own inverter model
    assert commission_hint(["speed error"], motor, lab) is None  # not an identification check
    commissioned = motor + "commissioning: {nominal: {}}\n"
    assert commission_hint(failed, commissioned, lab) is None
