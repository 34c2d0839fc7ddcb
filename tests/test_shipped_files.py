"""Shipped profiles, motors, rigs, maps and sweeps as a new user meets them: bare names from any
directory, a file path winning over a name, copies elsewhere, hints for names written otherwise
or of another kind, and `pmsm-hil profiles`."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from cli_helpers import cli

from pmsm_hil.profiles import ProfileError, load_profile
from pmsm_hil.profiles.shipped import resolve, shipped, shipped_root


def test_bare_names_find_the_shipped_files_from_any_directory(tmp_path):
    assert (
        Path(resolve("paper-a", "profile")).read_text()
        == (shipped_root() / "paper-a.yaml").read_text()
    )
    assert resolve("lab-typical", "rig").endswith(os.path.join("rigs", "lab-typical.yaml"))
    assert resolve("sew-cm3c80s.yaml", "motor").endswith(os.path.join("motors", "sew-cm3c80s.yaml"))
    profile = load_profile(
        resolve("paper-a", "profile"), rig_override=resolve("lab-typical", "rig")
    )
    assert profile.rig.enabled("dead_time") and profile.motor.name == "paper-a-ipmsm"
    assert {p.stem for p in shipped("rig")} >= {"default", "lab-typical", "ideal"}


def test_a_file_path_wins_over_a_shipped_name(tmp_path):
    mine = tmp_path / "paper-a.yaml"
    mine.write_text("name: mine\n")
    assert resolve("paper-a.yaml", "profile") == "paper-a.yaml"  # the working directory's file
    assert resolve("paper-a", "profile") != "paper-a"  # no such file: the shipped one


def test_a_shipped_profile_copied_elsewhere_finds_the_shipped_motor_rig_and_maps(tmp_path):
    """The first thing a user does with a shipped profile is copy it to edit it: its motor and rig
    (written relative to the shipped tree) are then not beside it. The shipped files of those
    names are used, each with a note naming the line; a bare name works as on the command line."""
    text = (shipped_root() / "paper-a.yaml").read_text()
    (tmp_path / "mine.yaml").write_text(text)
    p = load_profile(str(tmp_path / "mine.yaml"), rig_override=resolve("lab-typical", "rig"))
    assert p.motor.path == str(shipped_root() / "motors" / "paper-a-ipmsm.yaml")
    assert any("mine.yaml:11: motor" in w and "'paper-a-ipmsm' is used" in w for w in p.warnings)
    assert p.rig.flux_map() is not None  # lab-typical's map, shipped beside it
    named = text.replace("motors/paper-a-ipmsm.yaml", "paper-a-ipmsm").replace(
        "rigs/default.yaml", "lab-typical"
    )
    (tmp_path / "named.yaml").write_text(named)
    p = load_profile(str(tmp_path / "named.yaml"))
    assert p.rig.enabled("saturation") and p.motor.name == "paper-a-ipmsm"
    # a motor of its own beside the profile wins; one that exists nowhere is reported at its line
    (tmp_path / "motors").mkdir()
    mine = (shipped_root() / "motors" / "paper-a-ipmsm.yaml").read_text()
    (tmp_path / "motors" / "paper-a-ipmsm.yaml").write_text(
        mine.replace("psi_f_wb: 0.18", "psi_f_wb: 0.19")
    )
    p = load_profile(str(tmp_path / "mine.yaml"))
    assert p.motor.path == str(tmp_path / "motors" / "paper-a-ipmsm.yaml")
    assert p.motor.psi_f_wb == 0.19
    assert not any("motor =" in w for w in p.warnings)
    (tmp_path / "typo.yaml").write_text(
        text.replace("motors/paper-a-ipmsm.yaml", "motors/paper-q.yaml")
    )
    with pytest.raises(ProfileError) as e:
        load_profile(str(tmp_path / "typo.yaml"))
    assert "typo.yaml:11: motor = 'motors/paper-q.yaml'" in str(e.value)
    r = cli(
        "run",
        tmp_path / "mine.yaml",
        "--stop-after",
        "0.05",
        "--no-live",
        "-o",
        tmp_path / "m.mcap",
    )
    assert r.returncode == 0, r.stderr
    assert "stopped after 0.05 s of device time, as --stop-after asked" in r.stdout


def test_an_unknown_name_lists_what_is_shipped(tmp_path):
    with pytest.raises(ProfileError) as e:
        resolve("paper-z", "profile")
    assert "paper-z" in str(e.value) and "paper-a-identify" in str(e.value)
    r = cli("run", "paper-z")
    assert r.returncode == 2 and "paper-z" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize(
    ("name", "kind", "hint"),
    [
        ("Paper-A", "profile", "did you mean 'paper-a'?"),
        ("paper_a_identify", "profile", "did you mean 'paper-a-identify'?"),
        ("labtypical", "rig", "did you mean 'lab-typical'?"),
        ("sew", "rig", "did you mean 'sew-cm3c80s'?"),
        ("paper-b-", "profile", "did you mean 'paper-b'?"),
        ("paper-a-s", "profile", "did you mean 'paper-a-sensorless'?"),
        ("paper", "profile", "did you mean one of 'paper-a-identify', 'paper-a-sensorless'"),
        ("tolerance", "profile", "'tolerance' is a sweep: `pmsm-hil sweep tolerance`"),
        ("paper-a", "sweep", "'paper-a' is a profile: `pmsm-hil run paper-a`"),
        ("lab-typical", "motor", "'lab-typical' is a rig: `--rig lab-typical`"),
        # another kind written otherwise, and this kind before another of the same name
        ("labtypical", "profile", "'lab-typical' is a rig: `--rig lab-typical`"),
        ("Tolerance", "profile", "'tolerance' is a sweep: `pmsm-hil sweep tolerance`"),
        ("SEW-cm3c80s", "profile", "did you mean 'sew-cm3c80s'?"),
    ],
)
def test_a_name_written_otherwise_or_of_another_kind_gets_a_hint(name, kind, hint):
    with pytest.raises(ProfileError) as e:
        resolve(name, kind)
    assert hint in str(e.value)


def test_a_path_to_nothing_with_a_shipped_name_gives_the_bare_name(tmp_path):
    """The README's `profiles/paper-a.yaml` from another directory: the error says what to type."""
    r = cli("run", "profiles/paper-a.yaml", "--no-live", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "profiles/paper-a.yaml: no such file" in r.stderr and "bare name: paper-a" in r.stderr
    r = cli("run", "paper-a", "--rig", "x/lab-typical.yaml", "--no-live", cwd=tmp_path)
    assert r.returncode == 2 and "shipped rig" in r.stderr and "bare name: lab-typical" in r.stderr
    assert not (tmp_path / "runs").exists()


def test_profiles_command_lists_the_shipped_files():
    r = cli("profiles")
    assert r.returncode == 0, r.stderr
    for name in ("paper-a", "paper-a-identify", "sew-cm3c80s", "lab-typical", "effect-dead-time"):
        assert name in r.stdout
    # a motor file says what machine it is (its data: motor files carry no description field)
    line = next(x for x in r.stdout.splitlines() if x.split()[:1] == ["paper-b-spmsm"])
    assert "SPMSM, p = 4, R 2.875 ohm, L_d 8.5 mH" in line
    # a profile says what `pmsm-hil test` judges it on
    row = {x.split()[0]: x for x in r.stdout.splitlines() if x.split()}
    assert "identification (4)" in row["paper-a-identify"]
    assert "speed_error, recovery" in row["paper-a"]
    assert row["paper-b"].rstrip().endswith(" -")  # none: complete, no fault


def test_profiles_paths_are_whole_from_a_deep_install(tmp_path, monkeypatch, capsys):
    """`pmsm-hil profiles --paths` piped: every path whole on its line, ready to copy (a user
    venv's site-packages made them longer than the table and they were cut with an ellipsis)."""
    from pmsm_hil.cli.main import main as cli_main
    from pmsm_hil.profiles import shipped as shipped_mod

    deep = tmp_path / ("x" * 40) / "lib" / "python3.11" / "site-packages" / "pmsm_hil" / "shipped"
    (deep / "rigs").mkdir(parents=True)
    rig = deep / "rigs" / "effect-adc-quantisation.yaml"
    rig.write_text("name: q\n")
    monkeypatch.setattr(shipped_mod, "_root", lambda kind: deep)
    assert cli_main(["profiles", "--paths"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.split()[:1] == [rig.stem])
    assert str(rig) in line, out


def test_every_motor_field_has_its_row_in_docs_profiles(root):
    """docs/profiles.md's motor table names every field the motor file takes, and no other (a
    walk found four sensorless fields that the unknown-field error listed but the table did not)."""
    import re

    from pmsm_hil.profiles.motor import Motor

    doc = (root / "docs" / "profiles.md").read_text(encoding="utf-8")
    section = doc[doc.index("\n## Motor") :]
    section = section[: section.index("\n## ", 5)]
    first_cells = [line.split("|")[1] for line in section.splitlines() if line.startswith("| `")]
    named = {n for cell in first_cells for n in re.findall(r"`([a-z_0-9]+)`", cell)}
    assert sorted(set(Motor.model_fields) - named) == []
    assert sorted(named - set(Motor.model_fields)) == []


def test_the_installed_package_is_marked_typed(built_package):
    """PEP 561's py.typed is installed with the package, so that mypy or pyright in a user's
    script reads pmsm_hil's annotations instead of skipping it (`module is installed, but missing
    library stubs or py.typed marker`)."""
    assert (built_package / "pmsm_hil" / "py.typed").is_file()


def test_a_loader_given_a_shipped_name_says_how_to_get_its_path(tmp_path, monkeypatch):
    """In a script, `load_profile("paper-a")` (the CLI's bare name) finds no file: the error says
    that it is a shipped profile and which call gives its path."""
    from pmsm_hil.profiles import load_motor, load_rig
    from pmsm_hil.sweep import load_sweep

    monkeypatch.chdir(tmp_path)
    for load, name, kind in (
        (load_profile, "paper-a", "profile"),
        (load_motor, "paper-a-ipmsm.yaml", "motor"),
        (load_rig, "lab-typical", "rig"),
        (load_sweep, "tolerance", "sweep"),
    ):
        with pytest.raises(ProfileError) as e:
            load(name)
        stem = name.removesuffix(".yaml")
        assert f"is a shipped {kind}: its path is " in str(e.value)
        assert f"pmsm_hil.profiles.shipped.resolve({stem!r}, {kind!r})" in str(e.value)
        load(resolve(stem, kind))
    with pytest.raises(ProfileError) as e:
        load_profile("no-such-profile")
    assert "shipped" not in str(e.value)
