"""Did-you-mean (pmsm_hil.names): one matcher for every name that names nothing."""

from __future__ import annotations

import textwrap

import pytest

from pmsm_hil.names import closest, did_you_mean, same_name
from pmsm_hil.profiles import ProfileError, load_profile

FIELDS = ["name", "duration_s", "speed_rpm", "ramp_rpm_s", "load_nm", "capture", "speed_ref_rpm"]


@pytest.mark.parametrize(
    ("name", "want"),
    [
        ("Speed_RPM", ["speed_rpm"]),  # case
        ("speedRpm", ["speed_rpm"]),  # separators
        ("speed-rpm", ["speed_rpm"]),
        ("durationS", ["duration_s"]),
        ("speed", ["speed_rpm", "speed_ref_rpm"]),  # the beginning of two: both, in order
        ("ramp", ["ramp_rpm_s"]),  # the beginning of one
        ("laod_nm", ["load_nm"]),  # misspelt
        ("captures", ["capture"]),
        ("torque_nm", []),  # nothing close
        ("", []),
        ("__", []),
    ],
)
def test_closest(name, want):
    assert closest(name, FIELDS) == want


def test_a_short_beginning_or_one_of_many_suggests_nothing_by_itself():
    many = [f"seg_{i}" for i in range(10)]
    assert closest("sp", ["speed_rpm", "speed_ref_rpm"]) == []  # 2 characters: not a beginning
    assert closest("seg", many) == []  # ten begin so: too short to say which
    assert closest("seg_7", many) == ["seg_7"]


def test_same_name_is_case_and_separators_only():
    assert same_name("labtypical", ["default", "lab-typical"]) == "lab-typical"
    assert same_name("Lab_Typical", ["lab-typical"]) == "lab-typical"
    assert same_name("lab", ["lab-typical"]) is None  # a beginning is not the same name
    assert same_name("", ["lab-typical"]) is None


def test_did_you_mean_wording():
    assert did_you_mean("Paper-A", ["paper-a", "paper-a-identify"]) == "; did you mean 'paper-a'?"
    assert did_you_mean("lab", ["lab-typical", "lab-noisy"]) == (
        "; did you mean one of 'lab-typical', 'lab-noisy'?"
    )
    assert did_you_mean("labtypical", ["lab-typical"], "the shipped rig ") == (
        "; did you mean the shipped rig 'lab-typical'?"
    )
    assert did_you_mean("zzz", ["lab-typical"]) == ""
    assert closest("x", [None, 3, "x"]) == ["x"]  # names that are not text are skipped


def test_a_profile_field_written_in_another_case_is_named(tmp_path, monkeypatch):
    """Before the shared matcher, difflib on the raw names found nothing for `Speed_RPM`."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.yaml").write_text(
        textwrap.dedent(
            """\
            name: p
            motor: paper-a-ipmsm
            segments:
              - {duration_s: 1.0, Speed_RPM: 100}
            """
        )
    )
    with pytest.raises(ProfileError) as ei:
        load_profile("p.yaml")
    assert (
        "p.yaml:4: segments[0].Speed_RPM = 100 is not a field of segments[0]; "
        "did you mean 'speed_rpm'?"
    ) in [str(p) for p in ei.value.problems]
