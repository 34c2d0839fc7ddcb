"""The emulator sends /sim/truth at the profile's telemetry.truth_hz on every path (the pty child
of `pmsm-hil run`, the in-process emulator of `test` and sweeps), whatever the control period: the
sim board counts the rate in the firmware's periods from the run's start. It used to count a fixed
200 periods in the child (50 Hz at ts_s 100 us) and ignore truth_hz everywhere."""

from __future__ import annotations

import numpy as np
import pytest
from cli_helpers import cli

from pmsm_hil.device import DeviceSpec, open_device
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile


def _profile(tmp_path, data, ts_s: float, truth_hz: float | None):
    """tests/data/short.yaml (its motor and rig by absolute path) with ts_s and truth_hz."""
    src = (data / "short.yaml").read_text()
    src = src.replace("../../profiles/", str(data.parent.parent / "profiles") + "/")
    tel = "" if truth_hz is None else f"telemetry: {{truth_hz: {truth_hz}}}\n"
    src = src.replace("segments:", f"control: {{ts_s: {ts_s}}}\n{tel}segments:")
    p = tmp_path / f"p-{ts_s}-{truth_hz}.yaml"
    p.write_text(src)
    return p


def _spacing(log_path) -> float:
    t = read_log(str(log_path)).topic("/sim/truth")["t_s"]
    assert len(t) > 10
    return float(np.median(np.diff(t)))


@pytest.mark.parametrize(
    "ts_s, truth_hz, spacing_s",
    [(100e-6, None, 0.01), (100e-6, 50, 0.02), (50e-6, 50, 0.02), (50e-6, 250, 0.004)],
)
def test_in_process_truth_at_the_profiles_rate(tmp_path, data, ts_s, truth_hz, spacing_s):
    profile = load_profile(str(_profile(tmp_path, data, ts_s, truth_hz)))
    link = open_device(DeviceSpec(in_process=True, seed=2), profile)
    out = tmp_path / "run.mcap"
    run_profile(profile, Session(link), out, RunOptions(seed=2))
    assert _spacing(out) == pytest.approx(spacing_s)


def test_run_on_the_emulator_child_sends_truth_at_the_profiles_rate(tmp_path, data):
    """`pmsm-hil run` (the emulator child on its pty) at ts_s 100 us: 100 Hz by default (it was
    50 Hz), 50 Hz when the profile asks for it."""
    for truth_hz, spacing_s in ((None, 0.01), (50, 0.02)):
        p = _profile(tmp_path, data, 100e-6, truth_hz)
        out = tmp_path / f"{truth_hz}.mcap"
        r = cli("run", p, "--no-live", "-o", out)
        assert r.returncode == 0, r.stderr
        assert _spacing(out) == pytest.approx(spacing_s)


def test_emulate_refuses_a_negative_truth_rate():
    r = cli("emulate", "--truth-hz", "-5")
    assert r.returncode == 2
    assert "--truth-hz -5: must be 0..50000 Hz" in r.stderr
