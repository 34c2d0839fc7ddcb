"""CAN as other tools and other nodes see it: frames of another node on the drive's identifiers,
the DBC's value tables, the DBC installed with the package (docs/can.md)."""

from __future__ import annotations

import cantools

from pmsm_hil.analysis.summary import summarize_log
from pmsm_hil.device import apply_can_rates, inprocess_can_link
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile


def test_frames_the_drive_rejects_are_in_the_run_summary(data, tmp_path):
    """Another node sends on one of the drive's identifiers (0x181, a CANopen TPDO1 of node 1, is
    sim_plant's first frame for node 1, 8 octets instead of 7): the firmware rejects each and
    counts it in rx_bad, and the run summary says so, as docs/faults.md promises (it read only
    tx_dropped of /pmsm/status and never said it)."""
    profile = load_profile(str(data / "short.yaml"))
    apply_can_rates(profile)
    settings = emulator_settings(
        profile.motor, profile.rig, seed=1, baud=profile.link.baud, ts_s=profile.control.ts_s
    )
    foreign = []

    def other_node(frames):
        if any(ident == 0x031 for ident, _ in frames):  # beside each heartbeat
            foreign.append(1)
            return [*frames, (0x181, bytes(range(8)))]
        return frames

    def toward_host(frames):  # a CANopen heartbeat of node 1 beside the drive's frames
        return [*frames, (0x701, bytes([5]))] if frames else frames

    link = inprocess_can_link(settings, fault_h2d=other_node, fault_d2h=toward_host)
    out = tmp_path / "shared.mcap"
    run_profile(profile, Session(link), out, RunOptions(capture=False))  # the whole profile
    assert len(foreign) >= 5
    summary = summarize_log(out)
    problems = summary.problems
    assert any("the device rejected" in p for p in problems), problems
    # the host's count of frames it does not know is said too, and the verdict names what is
    # missing rather than calling a whole file damaged
    assert any("frames of an identifier it does not know" in p for p in problems), problems
    from pmsm_hil.analysis.summary_text import verdict_text

    verdict = verdict_text(summary)
    assert "the file is damaged" not in verdict
    assert "INCOMPLETE[/] (the record is not whole: the device rejected" in verdict, verdict
    assert verdict.endswith("): the segments are within bounds"), verdict


def test_the_dbc_names_enum_values_as_the_log_does(root):
    """A CAN analyser shows `running`, `nominal`, `config_ctrl`, not 1, 0, 3: every field whose
    yaml comment names an enum has its value table, and a transfer header's msg_id too."""
    from pmsm_hil.protocol import can_generated as cg
    from pmsm_hil.protocol import generated as gen
    from pmsm_hil.protocol.can_link import encode_message

    db = cantools.database.load_file(str(root / "firmware" / "proto" / "pmsm_proto.dbc"))
    state = gen.ENUMS["state"]
    est = gen.ENUMS["estimator"]
    ((ident, data), *_) = encode_message(
        "status",
        5,
        tick=1,
        state=state["running"],
        segment=0,
        faults=0,
        v_dc_v=540.0,
        tx_dropped=0,
        rx_bad=0,
        rx_frames=0,
        hb_age_ms=0,
        capture_count=0,
    )
    assert str(db.decode_message(ident, data)["state"]) == "running"
    ((ident, data), *_) = encode_message(
        "params",
        6,
        tick=1,
        estimator=est["rls"],
        flags=0,
        l_d_h=0.005,
        l_q_h=0.012,
        psi_f_wb=0.18,
        r_s_ohm=0.9,
    )
    assert str(db.decode_message(ident, data)["estimator"]) == "rls"
    head = bytes((0, gen.BY_NAME["config_ctrl"].id, 1, 100, 0, 0))
    msg = db.get_message_by_frame_id(cg.FUNC_TRANSFER_H2D << cg.NODE_BITS | cg.NODE)
    assert str(msg.decode(head, allow_truncated=True)["msg_id"]) == "config_ctrl"
    # bit masks keep their raw value (a value table would name only single bits)
    assert db.get_message_by_name("status_1").get_signal_by_name("faults").choices is None


def test_the_dbc_is_installed_and_profiles_prints_its_path(tmp_path, root, built_package):
    """docs/can.md named firmware/proto/pmsm_proto.dbc, which `pip install` left behind: a user
    of an installed pmsm-hil had no DBC. It is package data now, and `pmsm-hil profiles` says
    where."""
    import subprocess
    import sys

    from pmsm_hil.protocol import dbc_path

    lib = built_package
    installed = lib / "pmsm_hil" / "proto" / "pmsm_proto.dbc"
    assert installed.read_bytes() == (root / "firmware" / "proto" / "pmsm_proto.dbc").read_bytes()
    assert dbc_path().is_file()
    r = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", "profiles"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if "CAN database" in x)
    assert line.endswith(str(dbc_path())), line


def test_the_dbcs_integer_signals_carry_the_range_of_their_wire_type():
    """An analyser's [min|max] is the physical range the wire type carries (it was [0|0] for
    every signal): an i16 speed at 0.1 r/min spans -3276.8 .. 3276.7 r/min."""
    from pmsm_hil.protocol import dbc_path

    db = cantools.database.load_file(str(dbc_path()))
    speed = db.get_message_by_name("telem_fast_1").get_signal_by_name("speed_rpm")
    assert (speed.minimum, speed.maximum) == (-3276.8, 3276.7)
    # (a transfer's `data` is 7 raw payload octets, not a quantity: no range)
    ints = [s for m in db.messages for s in m.signals if not s.is_float and s.name != "data"]
    assert ints and all(s.minimum is not None and s.maximum > s.minimum for s in ints)
    floats = [s for m in db.messages for s in m.signals if s.is_float]
    assert floats and all(s.minimum is None for s in floats)  # an f32 carries no fixed range
