"""Acceptance criteria in profiles and `pmsm-hil test`: validation, no effect on the device, the
pass/fail table, JUnit XML, the exit code."""

from __future__ import annotations

import re
import subprocess
import xml.etree.ElementTree as ET

import pytest
from cli_helpers import CLI
from emu_helpers import DEVICE_TOPICS, raw_messages, run_inproc

from pmsm_hil.profiles import ProfileError, load_profile


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
        # a bound of 0 or below fails every plateau: refused like the other bounds
        (
            "acceptance:\n  run:\n    speed_error_max_rpm: -5\n",
            "acceptance.run.speed_error_max_rpm",
            "= -5 must be > 0 r/min",
        ),
        # a union's members make one message, not one per member (`.float`, `.literal['band']`)
        (
            "acceptance:\n  run:\n    speed_error_max_rpm: 5 rpm\n",
            "acceptance.run.speed_error_max_rpm",
            "= '5 rpm' is not a number or 'band' (write the number alone",
        ),
        (
            "acceptance:\n  segments:\n    - {segment: 1.5, recovery_max_s: 0.3}\n",
            "acceptance.segments[0].segment",
            "is not text or a whole number (the segment's name or index)",
        ),
        (
            "acceptance:\n  run:\n    identification:\n      - {estimator: rls, param: l_q_h, error_max_rel: 0.02}\n",
            "acceptance.run.identification",
            "the profile does not identify (control.identify is not true)",
        ),
        (
            "acceptance:\n  run: {complete: false, faults: ignored}\n",
            "acceptance.run",
            "checks nothing",
        ),
        # one segment's bound twice, by index and by name: which would judge it is a guess
        (
            "acceptance:\n  segments:\n    - {segment: 1, recovery_max_s: 0.2}\n"
            '    - {segment: "load on", recovery_max_s: 0.3}\n',
            "acceptance.segments[1].recovery_max_s",
            "= 0.3 bounds segment 1 again (acceptance.segments[0] bounds it already)",
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
    assert ".constrained-float" not in msg and ".str" not in msg and ".int" not in msg


def test_an_identification_bound_given_twice_is_refused(tmp_path, data):
    """Two bounds on one estimator's parameter: refused on the second one's line (which would judge
    is a guess); the same parameter's other bound, or another estimator's, is not a repeat."""
    p = with_acceptance(
        tmp_path,
        data,
        "acceptance:\n  run:\n    identification:\n"
        "      - {estimator: nlms_adaline, param: l_q_h, error_max_rel: 0.02}\n"
        "      - {estimator: rls, param: l_q_h, error_max_rel: 0.02}\n"
        "      - {estimator: nlms_adaline, param: l_q_h, conv_max_s: 0.5}\n"
        "      - {estimator: nlms_adaline, param: l_q_h, error_max_rel: 0.5}\n",
    )
    p.write_text(p.read_text().replace("segments:", "control: {identify: true}\nsegments:", 1))
    with pytest.raises(ProfileError) as e:
        load_profile(p)
    assert len(e.value.problems) == 1, str(e.value)
    line = (
        p.read_text()
        .splitlines()
        .index("      - {estimator: nlms_adaline, param: l_q_h, error_max_rel: 0.5}")
    )
    assert str(e.value) == (
        f"{p}:{line + 1}: acceptance.run.identification[3].error_max_rel = 0.5 bounds nlms_adaline "
        "l_q_h again (acceptance.run.identification[0] bounds it already): give each bound once"
    )


def test_one_segment_may_take_its_bounds_in_several_items(tmp_path, data):
    """Two items on one segment are fine while they bound different quantities."""
    p = with_acceptance(
        tmp_path,
        data,
        "acceptance:\n  segments:\n    - {segment: 1, recovery_max_s: 0.2}\n"
        '    - {segment: "load on", ripple_q_max_a: 2.0}\n',
    )
    acc = load_profile(p).acceptance
    assert acc is not None and len(acc.segments) == 2


def test_an_empty_acceptance_section_is_warned_of_at_its_line(tmp_path, data):
    """`acceptance:` with nothing under it (criteria not indented, say) is the defaults only: the
    profile loads, with a warning naming the line; a section that is not there says nothing."""
    p = with_acceptance(tmp_path, data, "acceptance:\nrun:\n  speed_error_max_rpm: 2\n")
    with pytest.raises(ProfileError):  # the criteria at the top level: an unknown field
        load_profile(p)
    p = with_acceptance(tmp_path, data, "acceptance:\n")
    line = p.read_text().splitlines().index("acceptance:") + 1
    prof = load_profile(p)
    assert prof.acceptance is None
    said = [w for w in prof.warnings if "acceptance: is empty" in w]
    assert said == [
        f"{p}:{line}: acceptance: is empty (its criteria not indented under it?): a run is "
        "judged on the defaults only, complete and no fault"
    ]
    assert not [w for w in load_profile(data / "short.yaml").warnings if "acceptance" in w]


def test_an_unnamed_segment_is_pointed_to_its_index(tmp_path, data):
    text = re.sub(r'name: "load off",\s*', "", (data / "short.yaml").read_text())
    assert '"load off"' not in text
    text = text.replace("../../profiles/", str(data.parent.parent / "profiles") + "/")
    p = tmp_path / "p.yaml"
    p.write_text(
        text + 'acceptance:\n  segments:\n    - {segment: "segment 2", recovery_max_s: 0.3}\n'
    )
    with pytest.raises(ProfileError) as e:
        load_profile(p)
    assert "an unnamed segment is given by its index: segment: 2" in str(e.value)


def _seg(i, name, setpoint=500.0, mean=0.1, rec=None, judged=True, faults=0):
    from pmsm_hil.analysis.summary import SegmentStats

    return SegmentStats(
        index=i,
        name=name,
        t_start_s=float(i),
        t_end_s=i + 1.0,
        setpoint_rpm=setpoint,
        load_nm=0.0,
        load_step_nm=0.0,
        band_rpm=5.0,
        mean_error_rpm=mean,
        mean_ok=True,
        true_mean_error_rpm=None,
        recovery_s=rec,
        recovery_ok=None,
        ripple_d_a=0.2,
        ripple_q_a=0.3,
        faults=faults,
        plateau_s=1.0 if judged else 0.05,
        mean_judged=judged,
    )


def _summary(segs, faults=()):
    from pmsm_hil.analysis.summary import RunSummary

    s = RunSummary(path="x", ended="profile end", expected=[g.name for g in segs])
    s.segments = list(segs)
    s.faults = list(faults)
    return s


def _checks(acc: dict, summary):
    from pmsm_hil.analysis.acceptance import evaluate
    from pmsm_hil.profiles.acceptance import Acceptance

    return evaluate(Acceptance.model_validate(acc), summary)


def test_a_segments_own_bound_replaces_the_run_wide_one_there():
    """A segment's own bound loosens (or tightens) the run's for that segment: one check, its
    own; the run-wide bound still judges the other segments; rows ordered by segment."""
    segs = [_seg(0, "a", mean=0.3), _seg(1, "b", mean=3.0), _seg(2, "c", mean=0.2)]
    acc = {
        "run": {"speed_error_max_rpm": 1.0},
        "segments": [{"segment": "b", "speed_error_max_rpm": 5}],
    }
    checks = [c for c in _checks(acc, _summary(segs)) if c.criterion == "speed error"]
    assert [(c.scope, c.bound, c.passed) for c in checks] == [
        ("segment 0 'a'", "|.| <= 1 r/min", True),
        ("segment 1 'b'", "|.| <= 5 r/min", True),
        ("segment 2 'c'", "|.| <= 1 r/min", True),
    ]
    # without its own bound, b fails the run's
    checks = _checks({"run": {"speed_error_max_rpm": 1.0}}, _summary(segs))
    assert [c.passed for c in checks if c.scope.startswith("segment 1")] == [False]


def test_ramps_and_stops_are_not_judged_run_wide_and_a_segments_own_bound_says_why():
    segs = [
        _seg(0, "ramp", mean=-1.05, judged=False),
        _seg(1, "stop", setpoint=0.0, rec=float("inf")),
        _seg(2, "hold", rec=float("inf")),
    ]
    acc = {"run": {"speed_error_max_rpm": 10, "ripple_q_max_a": 1, "recovery_max_s": 0.3}}
    checks = _checks(acc, _summary(segs))
    scopes = {c.scope for c in checks}
    assert "segment 0 'ramp'" not in scopes and "segment 1 'stop'" not in scopes
    rec = next(c for c in checks if c.criterion == "recovery")
    assert rec.scope == "segment 2 'hold'" and rec.measured == "never" and not rec.passed
    own = _checks({"segments": [{"segment": 0, "speed_error_max_rpm": 10}]}, _summary(segs))
    speed = next(c for c in own if c.criterion == "speed error")
    assert not speed.passed and speed.measured.startswith("not judged: a ramp")


def test_faults_are_forbidden_by_default_named_and_can_be_ignored():
    segs = [_seg(0, "a")]
    faulted = _summary(segs, faults=["1.234 s lost_lock"])
    for acc in ({}, {"segments": [{"segment": 0, "ripple_q_max_a": 1}]}, {"run": {}}):
        f = next(c for c in _checks(acc, faulted) if c.criterion == "faults")
        assert (f.measured, f.bound, f.passed) == ("1 (lost_lock)", "none", False)
    assert not [
        c for c in _checks({"run": {"faults": "ignored"}}, faulted) if c.criterion == "faults"
    ]
    expected = next(
        c for c in _checks({"run": {"faults": "expected"}}, faulted) if c.criterion == "faults"
    )
    assert expected.passed


def test_a_tiny_error_is_shown_with_its_digits():
    """A 3e-05 r/min error beside a 0.0001 bound was shown as +0.000 (failing 0 against 1e-4):
    the bound's resolution and two digits more."""
    checks = _checks({"run": {"speed_error_max_rpm": 1e-4}}, _summary([_seg(0, "a", mean=3e-5)]))
    c = next(c for c in checks if c.criterion == "speed error")
    assert c.measured == "+0.000030 r/min" and c.passed


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
    # without a `run:` section the run-wide defaults hold (complete, no fault); the second
    # profile of the same name is told apart by its ordinal
    assert "FAIL short: 3 of 4 checks passed" in r.stdout
    assert "PASS short (2): 2 of 2 checks passed" in r.stdout
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
    from pmsm_hil.analysis.summary import RunSummary, SegmentStats
    from pmsm_hil.analysis.summary_text import verdict_text

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
    assert "segment 2 'c' recovery 1.50 s (bound 0.3 s)" in v


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


def test_test_junit_for_ci_a_blip_segment_and_a_name_with_brackets(tmp_path, data):
    """`--junit` into a folder not made yet (made before the run); the report's root carries the
    totals, each suite its properties first (profile, rig, motor, seed), each failure a type and
    a body; a 1 ms segment is listed as too short to measure (it vanished from the summary, and
    the run counted as complete); a profile name with rich markup is printed as it is."""
    src = (data / "short.yaml").read_text()
    src = src.replace("../../profiles/", str(data.parent.parent / "profiles") + "/")
    src = src.replace("name: short", 'name: "rig A [/] B"')
    src = src.replace(
        '  - {name: "load off"',
        '  - {name: "blip", duration_s: 0.001, speed_rpm: 500, ramp_rpm_s: 0, load_nm: 5.0}\n'
        '  - {name: "load off"',
    )
    p = tmp_path / "blip.yaml"
    p.write_text(src + 'acceptance:\n  segments:\n    - {segment: "blip", ripple_q_max_a: 5}\n')
    junit = tmp_path / "new" / "sub" / "out.xml"
    r = subprocess.run(
        [*CLI, "test", str(p), "--junit", str(junit)], capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    # the title wraps where the temporary folder's path is long (80 columns without a terminal)
    assert "rig A [/] B (" in " ".join(r.stdout.split())
    assert "FAIL rig A [/] B: 2 of 3 checks passed" in r.stdout
    assert "not judged: too short to measure" in r.stdout
    assert "--out DIR keeps them" in r.stdout  # a failure in CI leaves something to look into
    root = ET.parse(junit).getroot()
    assert (root.get("tests"), root.get("failures"), root.get("errors")) == ("3", "1", "0")
    suite = root.find("testsuite")
    assert suite[0].tag == "properties"
    props = {q.get("name"): q.get("value") for q in suite[0]}
    assert props["profile"] == str(p) and props["seed"] == "1"
    assert props["rig"] == "default" and props["motor"]
    failure = suite.find("testcase/failure")
    assert failure.get("type") == "acceptance"
    assert "segment 2 'blip': ripple i_q measured not judged" in failure.text
    # a folder for the report is refused before anything runs
    r = subprocess.run(
        [*CLI, "test", str(p), "--junit", str(tmp_path)], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 2 and "is a folder" in r.stderr and "Traceback" not in r.stderr


def test_test_names_every_bad_profile_not_only_the_first(tmp_path, data):
    a = with_acceptance(tmp_path, data, "acceptance:\n  run: {faults: sometimes}\n", "a.yaml")
    b = with_acceptance(tmp_path, data, "acceptance:\n  run: {recovery_max_s: -1}\n", "b.yaml")
    r = subprocess.run([*CLI, "test", str(a), str(b)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"{a}:" in r.stderr and f"{b}:" in r.stderr
