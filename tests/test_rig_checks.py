"""Rig values the emulated plant refuses are refused when the profile is loaded: exit 2 with
file:line, field and value, no traceback (pmsm_hil.profiles.rig.plant_problems)."""

import re
import subprocess
import sys

import pytest

from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.profiles import load_profile
from pmsm_hil.profiles.fluxmap import MAX_NODES
from pmsm_hil.profiles.motor import load_motor
from pmsm_hil.profiles.rig import PLANT_DELAY_RING, PLANT_THERMAL_DIV, load_rig

# (file text of the effects section, profile control.ts_s, field named, value named)
BAD = {
    "cogging_not_multiple": (
        "  cogging: {amplitude_nm: 0.1, periods_per_rev: 30}\n",
        None,
        "effects.cogging.periods_per_rev",
        "30",
    ),
    "cogging_order": (
        "  cogging: {amplitude_nm: 0.1, periods_per_rev: 8000}\n",
        None,
        "effects.cogging.periods_per_rev",
        "8000",
    ),
    "dead_time": (
        "  dead_time: {dead_time_s: 2.0e-5}\n",
        20e-6,
        "effects.dead_time.dead_time_s",
        "2e-05",
    ),
    "thermal": (
        "  thermal: {c_winding_j_k: 0.001}\n",
        None,
        "effects.thermal.c_winding_j_k",
        "0.001",
    ),
}


def _write(tmp_path, root, effects: str, ts_s):
    rig = tmp_path / "bad.yaml"
    rig.write_text("name: bad\neffects:\n" + effects)
    profile = root / "profiles" / "paper-a.yaml"
    if ts_s is not None:
        text = profile.read_text()
        text = re.sub(r"(?m)^(\s*ts_s:\s*)[^#\n]+", rf"\g<1>{ts_s!r}  ", text, count=1)
        text = text.replace("motor: motors/", f"motor: {root / 'profiles' / 'motors'}/")
        profile = tmp_path / "profile.yaml"
        profile.write_text(text)
    return profile, rig


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_rig_value_exits_2_naming_file_line_field(tmp_path, root, case):
    effects, ts_s, field, value = BAD[case]
    profile, rig = _write(tmp_path, root, effects, ts_s)
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pmsm_hil.cli.main",
            "run",
            str(profile),
            "--rig",
            str(rig),
            "-o",
            str(tmp_path / "out.mcap"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    out = r.stdout + r.stderr
    assert r.returncode == 2, out
    assert "Traceback" not in out
    line = next((ln for ln in out.splitlines() if field in ln), None)
    assert line is not None, out
    assert re.search(re.escape(str(rig)) + r":\d+", line), line
    assert value in line, line
    assert not (tmp_path / "out.mcap").exists()


def test_good_values_next_to_the_limits_load(tmp_path, root):
    ok = (
        "  cogging: {amplitude_nm: 0.1, periods_per_rev: 4000}\n"  # order 1000 at 4 pole pairs
        "  dead_time: {dead_time_s: 1.9e-5}\n"
        "  thermal: {c_winding_j_k: 1.0, c_magnet_j_k: 1.0, r_wa_k_w: 1.0, r_wm_k_w: 1.0, r_ma_k_w: 1.0}\n"
    )
    profile, rig = _write(tmp_path, root, ok, 20e-6)
    p = load_profile(profile, rig_override=rig)
    assert p.rig.effects.cogging.periods_per_rev == 4000
    # and the emulator accepts what the loader accepted
    s = emulator_settings(p.motor, p.rig, ts_s=p.control.ts_s)
    assert s["cog_order_e"] == 1000
    EmulatedDevice(s)


@pytest.mark.parametrize("case", ["cogging_order", "dead_time", "thermal"])
def test_what_the_loader_refuses_the_emulator_refuses(tmp_path, root, case):
    """The loader's checks mirror plant_cfg_check: bypassing them, the emulator's own check fails."""
    effects, ts_s, _, _ = BAD[case]
    _, rig_path = _write(tmp_path, root, effects, None)
    rig = load_rig(rig_path)  # the rig alone is well-formed
    motor = load_motor(root / "profiles" / "motors" / "paper-a-ipmsm.yaml")
    s = emulator_settings(motor, rig, ts_s=ts_s or 50e-6)
    with pytest.raises(ValueError, match="emulator settings"):
        EmulatedDevice(s)


def test_plant_limits_match_the_firmware_header(root):
    h = (root / "firmware" / "sim" / "plant.h").read_text()
    assert re.search(rf"#define PLANT_THERMAL_DIV\s+{PLANT_THERMAL_DIV}\b", h)
    assert re.search(rf"#define PLANT_DELAY_RING\s+{PLANT_DELAY_RING}\b", h)
    assert re.search(
        rf"#define PLANT_MAP_MAX_N\s+{MAX_NODES}\b", h
    )  # flux-map grid, checked by the loader


@pytest.mark.parametrize("saturation", ["  saturation: {}\n", "  saturation: {map: nope.csv}\n"])
def test_a_flux_map_problem_and_the_checks_against_the_motor_are_said_together(
    tmp_path, root, saturation
):
    """A saturation effect whose map is missing or unusable beside a cogging period that the
    motor's pole pairs do not divide: both in one pass (the map's problem used to hide the checks
    against the motor until it was mended)."""
    from pmsm_hil.profiles import ProfileError

    effects = "  cogging: {amplitude_nm: 0.1, periods_per_rev: 30}\n" + saturation
    profile, rig = _write(tmp_path, root, effects, None)
    with pytest.raises(ProfileError) as e:
        load_profile(profile, rig_override=rig)
    text = str(e.value)
    assert "effects.saturation" in text
    assert "effects.cogging.periods_per_rev" in text and "pole_pairs 4" in text, text
    with pytest.raises(ProfileError, match=r"effects\.saturation"):  # the rig alone: refused too
        load_rig(rig)
