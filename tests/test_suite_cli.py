"""`pmsm-hil test` as a CI job meets it: every bad input named at once, a JUnit report that is
XML whatever the names hold and says so when it cannot be written, the results table of `--out`."""

from __future__ import annotations

import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from cli_helpers import CLI, cli
from test_acceptance import with_acceptance


def test_test_out_keeps_the_results_table_of_one_profile_and_refuses_a_file(tmp_path, data):
    """`--out DIR` keeps the results table with one profile too (run in this process, not on
    Dask); an `--out` that is a file is bad input named as such before the run, not a scheduler
    that cannot be reached (exit 3)."""
    import pyarrow.parquet as pq

    p = with_acceptance(tmp_path, data, "")
    r = cli("test", str(p), "--out", str(tmp_path / "o"), timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    rows = pq.read_table(tmp_path / "o" / "results.parquet").to_pylist()
    assert [(row["index"], row["status"]) for row in rows] == [(0, "ok")]
    assert (tmp_path / "o" / "results.csv").is_file()
    assert rows[0]["log_path"] and Path(rows[0]["log_path"]).is_file()
    blocker = tmp_path / "afile"
    blocker.write_text("")
    junit = tmp_path / "j.xml"
    r = cli("test", str(p), "--out", str(blocker), "--junit", str(junit), timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"--out {blocker}: is a file; give a folder" in r.stderr
    assert "scheduler" not in r.stderr and "Traceback" not in r.stderr
    assert ET.parse(junit).getroot().find("testsuite/testcase").get("name") == "inputs"


def test_test_names_a_missing_profile_beside_the_bad_files(tmp_path, data):
    """A name that finds no profile does not hide the problems of the files given with it."""
    a = with_acceptance(tmp_path, data, "acceptance:\n  run: {faults: sometimes}\n", "a.yaml")
    b = with_acceptance(tmp_path, data, "acceptance:\n  run: {recovery_max_s: -1}\n", "b.yaml")
    junit = tmp_path / "out.xml"
    r = cli("test", str(a), "no-such-profile", str(b), "--junit", str(junit), timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    for named in (f"{a}:", "no-such-profile: is neither a file", f"{b}:"):
        assert named in r.stderr
    root = ET.parse(junit).getroot()  # the totals on the root, as for a suite that ran
    assert (root.get("tests"), root.get("failures"), root.get("errors")) == ("1", "0", "1")
    error = root.find("testsuite/testcase/error")
    assert f"{a}:" in error.text and "no-such-profile" in error.text and f"{b}:" in error.text


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (a full disk)")
def test_test_says_so_when_the_junit_report_cannot_be_written(tmp_path, data):
    """A report that cannot be written after the run (a full disk) is one error line and exit 2,
    not a traceback and not the suite's pass: CI would find no report."""
    p = with_acceptance(tmp_path, data, "")
    r = cli("test", str(p), "--junit", "/dev/full", timeout=300)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    assert "--junit /dev/full: cannot be written (No space left on device)" in r.stderr
    assert "PASS" in r.stdout  # the table was shown before


def test_junit_holds_characters_xml_cannot_as_escapes():
    """A control character in a profile's name or a run's error (a YAML "\\a", a device's bytes
    in a message) is written as \\xNN: before, the report was not XML and CI found none."""
    from pmsm_hil.sweep.suite import SuiteCase, junit_error, junit_xml

    case = SuiteCase(
        profile="p.yaml", name="bell\a \x1b[31mred", status="failed", error="got \x00\x1b"
    )
    root = ET.fromstring(junit_xml([case]))
    suite = root.find("testsuite")
    assert suite.get("name") == "bell\\x07 \\x1b[31mred"
    assert suite.find("testcase/error").get("message") == "got \\x00\\x1b"
    assert root.get("errors") == "1"
    error = ET.fromstring(junit_error("inputs", "x.yaml:2: name = '\x1b' ...")).find(".//error")
    assert error.text == "x.yaml:2: name = '\\x1b' ..."


def test_a_dotted_profile_name_is_not_split_into_a_package_by_ci():
    """Jenkins and GitLab read a JUnit classname's dots as packages: `paper-a.v2` showed as class
    `v2` of package `paper-a`. The suite keeps the name as it is."""
    from pmsm_hil.sweep.suite import SuiteCase, junit_xml

    case = SuiteCase(profile="p.yaml", name="paper-a.v2", status="failed", error="x")
    case.checks = [
        {"scope": "run", "criterion": "faults", "measured": 0, "bound": 0, "passed": True}
    ]
    root = ET.fromstring(junit_xml([case]))
    assert root.find("testsuite").get("name") == "paper-a.v2"
    assert {tc.get("classname") for tc in root.iter("testcase")} == {"paper-a_v2"}


def test_junit_cases_add_up_to_the_runs_time():
    """Every case had time="0": GitLab adds the cases' times and showed each profile as taking
    none. The run's wall time is now on its first case (the run's error case when it failed)."""
    from pmsm_hil.sweep.suite import SuiteCase, junit_xml

    check = {"scope": "run", "criterion": "faults", "measured": 0, "bound": 0, "passed": True}
    ok = SuiteCase(profile="a.yaml", name="a", status="ok", wall_s=1.25)
    ok.checks = [check, {**check, "criterion": "complete"}]
    failed = SuiteCase(profile="b.yaml", name="b", status="failed", error="x", wall_s=0.5)
    failed.checks = [check]
    root = ET.fromstring(junit_xml([ok, failed]))
    a, b = root.findall("testsuite")
    assert [tc.get("time") for tc in a.iter("testcase")] == ["1.250", "0"]
    assert [tc.get("time") for tc in b.iter("testcase")] == ["0.500", "0"]
    assert b.find("testcase").get("name") == "run"
    for s in (a, b):
        assert sum(float(tc.get("time")) for tc in s.iter("testcase")) == float(s.get("time"))
    assert root.get("time") == "1.750"


def test_an_interrupted_test_is_not_judged_and_exits_130(tmp_path, data):
    """Ctrl-C during the run: the motor stopped, the profile NOT JUDGED (before: FAIL, "complete:
    no (stopped: host stop)", exit 1, as if the drive had stopped on its own), exit 130 as for
    `run`, and the JUnit report says so (an error case of type `interrupted`)."""
    import os
    import signal
    import time

    tmp = tmp_path / "tmp"  # where the run writes its log: it runs once that file grows
    tmp.mkdir()
    junit = tmp_path / "j.xml"
    proc = subprocess.Popen(
        [*CLI, "test", str(data / "long.yaml"), "--junit", str(junit)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "TMPDIR": str(tmp)},
    )
    deadline = time.monotonic() + 60
    while not any(p.stat().st_size > 50_000 for p in tmp.rglob("run.mcap")):
        assert time.monotonic() < deadline and proc.poll() is None, "the run did not start"
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, out + err
    assert "NOT JUDGED long: interrupted" in out and "FAIL" not in out
    assert "interrupted: 1 of 1 profiles not judged" in err and "Traceback" not in err
    error = ET.parse(junit).getroot().find("testsuite/testcase/error")
    assert error.get("type") == "interrupted"


def test_an_interrupt_before_the_suite_ran_replaces_an_earlier_report(
    tmp_path, monkeypatch, capsys
):
    """Ctrl-C while the profiles load or the cluster starts: exit 130 and a JUnit report that says
    so, not an earlier suite's report left at --junit for CI to read as this one's."""
    from pmsm_hil.cli.main import main
    from pmsm_hil.sweep import suite

    junit = tmp_path / "j.xml"
    junit.write_text('<testsuites tests="1" failures="0" errors="0"/>')  # yesterday's pass

    def interrupted(*args, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(suite, "plan_suite", interrupted)
    assert main(["test", "paper-a", "--junit", str(junit)]) == 130
    err = capsys.readouterr().err
    assert "interrupted before the suite's results were written" in err
    case = ET.parse(junit).getroot().find("testsuite/testcase")
    assert case is not None and case.get("name") == "interrupted"
    assert "no profile judged" in case.find("error").get("message")


def test_an_interrupt_while_the_suite_module_loads_replaces_an_earlier_report(
    tmp_path, monkeypatch, capsys
):
    """Ctrl-C in the first third of a second, while `test` imports its suite module (numpy,
    the sweep's machinery): the same report of an interrupted suite, not yesterday's pass left
    at --junit (it was raised before the handler that writes it)."""
    import os
    import signal
    import sys

    import pmsm_hil.sweep
    from pmsm_hil.cli.main import main
    from pmsm_hil.sweep import suite

    class CtrlCOnce:  # a Ctrl-C (SIGINT to this process) as the suite module starts to load
        raised = False

        def find_spec(self, name, path=None, target=None):
            if name == "pmsm_hil.sweep.suite" and not self.raised:
                CtrlCOnce.raised = True
                os.kill(os.getpid(), signal.SIGINT)

    # as from a terminal: a suite started in the background of a non-interactive shell (CI)
    # inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    monkeypatch.setattr(pmsm_hil.sweep, "suite", suite)  # as it was, after the test
    monkeypatch.delitem(sys.modules, "pmsm_hil.sweep.suite")
    monkeypatch.setattr(sys, "meta_path", [CtrlCOnce(), *sys.meta_path])
    junit = tmp_path / "j.xml"
    junit.write_text('<testsuites tests="1" failures="0" errors="0"/>')  # yesterday's pass
    try:
        assert main(["test", "paper-a", "--junit", str(junit)]) == 130
    finally:
        signal.signal(signal.SIGINT, previous)
    assert CtrlCOnce.raised
    assert "interrupted before the suite's results were written" in capsys.readouterr().err
    case = ET.parse(junit).getroot().find("testsuite/testcase")
    assert case is not None and case.get("name") == "interrupted"
