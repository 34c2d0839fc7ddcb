"""The pytest plugin (pmsm_hil.testing): the hil_device fixture on the emulator, acceptance from a
test, the hil_rig marker and the options, as a user's own test suite meets them."""

from __future__ import annotations

import os

import pytest

pytest_plugins = ["pytester"]


def test_hil_device_runs_a_profile_and_judges_its_criteria(hil_device, data):
    assert hil_device.kind == "emulator" and not hil_device.is_rig
    run = hil_device.run(data / "short.yaml", seed=2)
    assert run.result.state == "done" and run.result.faults == 0
    assert run.log_path.is_file()
    assert [c.criterion for c in run.checks] == ["complete", "faults"]  # the default criteria
    run.assert_accepted()
    load_on = run.summary.segments[1]
    assert load_on.recovery_s is not None and load_on.recovery_s < 0.3


def test_paper_a_meets_its_acceptance_criteria(hil_device):
    run = hil_device.run("paper-a")
    run.assert_accepted()
    assert len(run.checks) == 20  # complete, faults, 12 plateaus, 6 load steps


def test_assert_accepted_names_the_failed_bound(hil_device, data, tmp_path):
    p = tmp_path / "tight.yaml"
    src = (
        (data / "short.yaml")
        .read_text()
        .replace("../../profiles/", str(data.parent.parent / "profiles") + "/")
    )
    p.write_text(src + "acceptance:\n  run: {recovery_max_s: 0.001}\n")
    run = hil_device.run(p, out=tmp_path / "tight.mcap")
    assert not run.accepted
    with pytest.raises(
        AssertionError, match=r"segment 1 'load on': recovery measured 0\.\d+ s, bound <= 0.001 s"
    ):
        run.assert_accepted()


@pytest.mark.hil_rig
def test_the_rig_plays_paper_a(hil_device):
    """Runs only with --hil-port or --hil-can: the same criteria on the real drive."""
    hil_device.run("paper-a").assert_accepted()


def test_marker_skips_without_a_rig_and_options_reach_the_fixture(pytester):
    pytester.makepyfile(
        test_user="""
        import pytest

        @pytest.mark.hil_rig
        def test_needs_rig(hil_device):
            assert hil_device.is_rig

        def test_options(hil_device):
            assert (hil_device.kind, hil_device.seed, hil_device.rig) == ("emulator", 5, "ideal")
    """
    )
    r = pytester.runpytest_subprocess(
        "--hil-seed", "5", "--hil-rig", "ideal", "-p", "no:cacheprovider"
    )
    r.assert_outcomes(passed=1, skipped=1)
    # a port that exists (the plugin opens it only when a test runs a profile)
    r = pytester.runpytest_subprocess("--hil-port", os.devnull, "-k", "needs_rig", "-rs")
    r.assert_outcomes(passed=1)
    r = pytester.runpytest_subprocess("--markers")
    r.stdout.fnmatch_lines(["*hil_rig: needs a rig's path*in-process emulator*"])


def test_the_rig_path_runs_a_profile_over_can(pytester, data):
    """`--hil-can emulator` takes the rig's path (a link opened by the device factory, the run
    over the protocol) with the emulator on CAN at the other end."""
    short = data / "short.yaml"
    pytester.makepyfile(
        test_user=f"""
        import pytest

        @pytest.mark.hil_rig  # the rig's path: runs with the emulator on CAN too
        def test_needs_rig(hil_device):
            assert hil_device.is_rig

        def test_on_can(hil_device):
            assert hil_device.kind == "can" and hil_device.is_rig
            run = hil_device.run({str(short)!r}, seed=3)
            assert run.result.state == "done" and run.result.faults == 0
            assert run.log_path.is_file()
            run.assert_accepted()
    """
    )
    r = pytester.runpytest_subprocess("--hil-can", "emulator", "-p", "no:cacheprovider")
    r.assert_outcomes(passed=2)


def _strict_profile(pytester, data):
    """short.yaml with a load-step recovery bound no run meets, in the test's folder."""
    strict = pytester.path / "strict.yaml"
    text = (data / "short.yaml").read_text()
    strict.write_text(text + "\nacceptance:\n  run:\n    recovery_max_s: 0.0001\n")
    return strict


def test_a_failed_acceptance_points_at_the_users_line(pytester, data):
    """A failing `assert_accepted()` shows the user's test line and the failed bounds, not the
    plugin's own code."""
    strict = _strict_profile(pytester, data)
    pytester.makepyfile(
        test_user=f"""
        def test_strict(hil_device):
            run = hil_device.run({str(strict)!r})
            run.assert_accepted()  # THE USER'S LINE
    """
    )
    r = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    r.assert_outcomes(failed=1)
    out = r.stdout.str()
    assert "THE USER'S LINE" in out and "recovery measured" in out and "bound <= 0.0001 s" in out
    assert "def assert_accepted" not in out and "testing.py" not in out


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            ["--hil-port", "/dev/ttyNOPE0"],
            "--hil-port /dev/ttyNOPE0: no such serial port (is the adapter plugged in?)",
        ),
        (
            ["--hil-can", "nosuchiface:x"],
            "--hil-can nosuchiface:x: unknown interface 'nosuchiface' (python-can interfaces: *",
        ),
        (["--hil-can", "socketcan:can0,node=99"], "--hil-can socketcan:can0,node=99: node 99 *"),
        (
            ["--hil-port", os.devnull, "--hil-can", "emulator"],
            f"--hil-port {os.devnull} and --hil-can emulator: give one of them *, not both",
        ),
        (["--hil-rig", "nosuch"], "--hil-rig nosuch: nosuch: is neither a file nor a shipped rig*"),
        (["--hil-seed", "-1"], "--hil-seed -1: give a whole number 0..2147483647"),
    ],
)
def test_a_bad_option_is_one_usage_error_before_any_test(pytester, options, message):
    """A bad --hil-* option is checked once when pytest starts: pytest's usage error (exit code 4)
    naming the option and its value, once, not a failed or erroring test per test."""
    pytester.makepyfile(
        test_user="""
        def test_one(hil_device):
            hil_device.run("paper-a")

        def test_two(hil_device):
            hil_device.run("paper-a")
    """
    )
    r = pytester.runpytest_subprocess(*options, "-p", "no:cacheprovider")
    assert r.ret == pytest.ExitCode.USAGE_ERROR
    r.stderr.fnmatch_lines([f"ERROR: {message}"])
    err = r.stderr.str()
    assert err.count("ERROR:") == 1 and "Traceback" not in err, err
    assert "--can nosuchiface" not in err  # the plugin's option, not the CLI's
    assert "test_one" not in r.stdout.str()  # no test ran


def test_a_relative_profile_path_is_the_working_directorys(pytester, data):
    """`hil_device.run("mine.yaml")` looks in the working directory pytest runs in, not beside the
    test file; `Path(__file__).parent / "mine.yaml"` (the documented form) finds it from anywhere."""
    suite = pytester.mkdir("suite")
    (suite / "mine.yaml").write_text((data / "short.yaml").read_text())
    (suite / "test_user.py").write_text(
        "from pathlib import Path\n"
        "import pytest\n"
        "from pmsm_hil.profiles import ProfileError\n\n"
        "def test_beside_the_test(hil_device):\n"
        "    run = hil_device.run(Path(__file__).parent / 'mine.yaml')\n"
        "    assert run.profile.name == 'short' and run.result.state == 'done'\n\n"
        "def test_relative_is_the_working_directorys(hil_device):\n"
        "    with pytest.raises(ProfileError, match='mine.yaml: is neither a file'):\n"
        "        hil_device.run('mine.yaml')\n"
    )
    r = pytester.runpytest_subprocess("suite", "-p", "no:cacheprovider")  # from the folder above
    r.assert_outcomes(passed=2)


def test_a_port_given_as_two_words_is_not_taken_for_the_rootdir_silently(pytester):
    """pytest looks for its ini file before it knows the plugin's options: `--hil-port /dev/X`
    roots it at /dev and the project's ini file goes unread. The plugin says so and names the
    form that avoids it (`--hil-port=/dev/X`), which finds the ini file."""
    pytester.makeini("[pytest]\naddopts = -p no:cacheprovider\n")
    pytester.makepyfile(test_user="def test_one():\n    pass\n")
    r = pytester.runpytest_subprocess("--hil-port", os.devnull, "--co")
    out = r.stdout.str()
    assert f"pytest took {os.devnull} (the value of --hil-port) for a test path" in out, out
    assert f"Write --hil-port={os.devnull} (one word)" in out
    r = pytester.runpytest_subprocess(f"--hil-port={os.devnull}", "--co")
    out = r.stdout.str()
    assert "configfile: tox.ini" in out, out  # makeini writes tox.ini
    assert "for a test path" not in out


def test_a_bad_profile_or_port_fails_at_the_users_line_without_the_library_frames(pytester):
    """`hil_device.run` raises a ProfileError, TransportError or DeviceError as itself (a test may
    expect it), shown at the test's line with its message: not pyserial's frames and pmsm-hil's
    (some 130 lines per test for a port that is not a serial port)."""
    pytester.makepyfile(
        test_user="""
        import pytest
        from pmsm_hil.errors import TransportError
        from pmsm_hil.profiles import ProfileError

        def test_name(hil_device):
            hil_device.run("paper-aa")  # THE NAME LINE

        def test_port(hil_device):
            hil_device.run("paper-a")  # THE PORT LINE

        def test_expected(hil_device):
            with pytest.raises((ProfileError, TransportError)):
                hil_device.run("paper-aa")
    """
    )
    r = pytester.runpytest_subprocess(f"--hil-port={os.devnull}", "-p", "no:cacheprovider")
    r.assert_outcomes(failed=2, passed=1)
    out = r.stdout.str()
    assert "THE NAME LINE" in out and "THE PORT LINE" in out
    assert "ProfileError: paper-aa: is neither a file nor a shipped profile" in out
    assert f"TransportError: {os.devnull} is not a serial port" in out
    assert "serialposix.py" not in out and "shipped.py" not in out and "testing.py" not in out
    assert len(out.splitlines()) < 60, out


def test_a_failed_test_over_can_shows_no_partial_read_warnings(pytester, data):
    """python-can's socketcand client logs every partial TCP read as a warning; pytest captures
    them, and a failed test over `--hil-can` showed them by the thousand under its report (the
    CLI silences them; so does the plugin)."""
    strict = _strict_profile(pytester, data)
    pytester.makepyfile(
        test_user=f"""
        def test_strict(hil_device):
            hil_device.run({str(strict)!r}).assert_accepted()
    """
    )
    r = pytester.runpytest_subprocess("--hil-can", "emulator", "-p", "no:cacheprovider")
    r.assert_outcomes(failed=1)
    out = r.stdout.str()
    assert "recovery measured" in out
    assert "Got incomplete message" not in out and "socketcand" not in out
