"""Helpers shared by the tests that run profiles on the in-process emulator."""
from __future__ import annotations

from mcap.reader import make_reader

from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile
from pmsm_hil.transport.inproc import InProcessTransport

DEVICE_TOPICS = ("/pmsm/telemetry", "/pmsm/params", "/pmsm/events", "/pmsm/capture", "/sim/truth")


def run_inproc(profile_path, out, seed=1, rig=None, **opts):
    profile = load_profile(str(profile_path), rig_override=rig)
    settings = emulator_settings(profile.motor, profile.rig, seed=seed, baud=profile.link.baud,
                                 ts_s=profile.control.ts_s)
    transport = InProcessTransport(settings)
    result = run_profile(profile, Session(transport), out, RunOptions(seed=seed, **opts))
    return profile, result


def raw_messages(path, topics=DEVICE_TOPICS):
    out = []
    with open(path, "rb") as f:
        for schema, channel, msg in make_reader(f).iter_messages(topics=list(topics)):
            out.append((channel.topic, msg.log_time, bytes(msg.data)))
    return out
