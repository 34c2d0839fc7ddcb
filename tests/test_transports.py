"""One test suite for every transport: serial (emulator pty), CAN (emulator socketcand), the in-process
loopbacks (serial framing and CAN frames), and a rig's serial port or CAN interface when one is
configured (PMSM_HIL_RIG_PORT=/dev/ttyUSB0, PMSM_HIL_RIG_CAN=SPEC; skipped otherwise)."""

from __future__ import annotations

import os

import pytest

from pmsm_hil.device import DeviceSpec, open_device
from pmsm_hil.errors import DeviceError
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, configure, run_profile

KINDS = [
    "serial-emulator",
    "can-emulator",
    "serial-inprocess",
    "can-inprocess",
    "serial-rig",
    "can-rig",
]


def open_link(kind: str, profile):
    """Every kind through the one device factory (pmsm_hil.device)."""
    if kind == "serial-rig":
        port = os.environ.get("PMSM_HIL_RIG_PORT")
        if not port:
            pytest.skip("no serial rig configured (PMSM_HIL_RIG_PORT)")
        return open_device(DeviceSpec(port=port), profile)
    if kind == "can-rig":
        spec = os.environ.get("PMSM_HIL_RIG_CAN")
        if not spec:
            pytest.skip("no CAN rig configured (PMSM_HIL_RIG_CAN)")
        return open_device(DeviceSpec(can=spec), profile)
    can = "emulator" if kind.startswith("can") else None
    return open_device(DeviceSpec(can=can, in_process=kind.endswith("inprocess")), profile)


@pytest.fixture(params=KINDS)
def link_and_profile(request, data):
    profile = load_profile(str(data / "short.yaml"))
    link = open_link(request.param, profile)
    yield link, profile, request.param
    link.close()


def test_hello_identifies_the_device(link_and_profile):
    link, _, _ = link_and_profile
    ident = Session(link).hello()
    assert ident.proto_version == gen.PROTOCOL_VERSION and ident.schema_hash == gen.SCHEMA_HASH


def test_commands_are_acknowledged_and_bad_values_refused(link_and_profile):
    link, profile, _ = link_and_profile
    s = Session(link)
    s.hello()
    configure(s, profile)
    with pytest.raises(DeviceError, match="bad_value"):
        s.request("profile_clear", n_segments=10_000)


def test_a_profile_runs_to_the_end_with_nothing_lost(link_and_profile, tmp_path):
    link, profile, kind = link_and_profile
    if kind.endswith("rig"):
        pytest.skip("a full run on a rig is left to the operator")
    result = run_profile(profile, Session(link), tmp_path / "t.mcap", RunOptions(seed=1))
    assert (result.state, result.stop_reason, result.faults) == ("done", "profile end", 0)
    assert result.live.seq_gaps == 0 and result.live.status["tx_dropped"] == 0
    assert result.capture_samples == 1024
