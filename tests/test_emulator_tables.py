"""The sim board's setting keys and truth order are one table (firmware/sim/emu_table.h), read by
the Python side through the C API; the settings the host builds for every rig file use only keys
of that table, and a key outside it is refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.emulator import fwlib
from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.profiles import load_rig
from pmsm_hil.profiles.motor import load_motor

ROOT = Path(__file__).resolve().parents[1]
ARRAY_KEYS = {"sat_psi_d_wb", "sat_psi_q_wb"}  # emu_set_array, not emu_set


def test_tables_come_from_the_c_board():
    table = (ROOT / "firmware" / "sim" / "emu_table.h").read_text()
    settings, truth = fwlib.SETTING_KEYS, fwlib.TRUTH_KEYS
    assert len(settings) == len(set(settings)) and len(truth) == len(set(truth))
    for key in settings + truth:
        assert f"X({key}," in table
    assert truth[:3] == ("t_s", "i_d_a", "i_q_a") and "tick" in truth
    assert {"enc_offset_m_rad", "i_a_offset_a", "i_c_gain"} <= set(settings)


@pytest.mark.parametrize("rig", sorted(p.name for p in (ROOT / "profiles" / "rigs").glob("*.yaml")))
def test_host_settings_use_only_table_keys(rig):
    motor = load_motor(ROOT / "profiles" / "motors" / "paper-a-ipmsm.yaml")
    s = emulator_settings(motor, load_rig(ROOT / "profiles" / "rigs" / rig))
    unknown = set(s) - set(fwlib.SETTING_KEYS) - ARRAY_KEYS
    assert not unknown, f"{rig}: settings outside firmware/sim/emu_table.h: {sorted(unknown)}"
    EmulatedDevice(s)  # and the board accepts every one of them


def test_unknown_key_is_refused():
    with pytest.raises(KeyError, match="i_gain_a"):
        EmulatedDevice({"i_gain_a": 1.0})


def test_truth_values_follow_the_table_order():
    dev = EmulatedDevice({"seed": 3})
    truth = dev.plant_truth()
    assert tuple(truth) == fwlib.TRUTH_KEYS
    assert truth["v_dc_v"] == pytest.approx(540.0) and truth["tick"] == 0.0
