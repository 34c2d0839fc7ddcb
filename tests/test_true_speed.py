"""The plant's own mean speed from the truth's angle (analysis.true_speed), for the summary's
"true err": not biased by a speed ripple at a multiple of truth_hz, which the truth's speed
samples see at the same phase every time."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from cli_helpers import cli

from pmsm_hil.analysis.summary import summarize_log
from pmsm_hil.analysis.true_speed import true_speed_correction_rpm

P = 4


def _plant(mean_rpm: float, ripple_rpm: float, ripple_hz: float, truth_hz: float, phase=1.0):
    """A speed rippling at ripple_hz, the truth sampled at truth_hz over 0.5 s: (truth instants,
    truth electrical angle wrapped, truth speed)."""
    tt = np.arange(0.0, 0.5 + 1e-9, 1.0 / truth_hz)
    w = 2 * math.pi * ripple_hz
    rpm = mean_rpm + ripple_rpm * np.sin(w * tt + phase)
    # angle = integral of the speed (electrical rad)
    theta = (mean_rpm * tt - ripple_rpm / w * (np.cos(w * tt + phase) - math.cos(phase))) * (
        math.pi / 30 * P
    )
    return tt, np.mod(theta, 2 * math.pi), rpm


@pytest.mark.parametrize("mean_rpm", [15.0, 1500.0, 3000.0])
def test_a_ripple_at_a_multiple_of_the_truth_rate_does_not_bias_it(mean_rpm):
    """600 Hz of 10 r/min sampled at 100 Hz: the truth's speed samples read 8.4 r/min high every
    time; the angle travelled gives the mean. The measurement (2 kHz) reads the mean."""
    tt, theta, rpm = _plant(mean_rpm, 10.0, 600.0, 100.0)
    t = np.arange(0.0, 0.5 + 1e-9, 1 / 2000)
    spd = np.full_like(t, mean_rpm)
    assert np.mean(rpm - mean_rpm) == pytest.approx(10 * math.sin(1.0), abs=0.05)  # the old way
    corr = true_speed_correction_rpm(t, spd, tt, theta, P)
    assert corr is not None and abs(corr) < 0.01


def test_a_measurement_that_reads_high_is_told():
    """An encoder read 0.2 % fast (a wrong line count by 2 in 1000) at 1500 r/min: the plant is
    3 r/min below what the drive measures."""
    tt, theta, _ = _plant(1500.0, 0.0, 600.0, 100.0)
    t = np.arange(0.0, 0.5 + 1e-9, 1 / 2000)
    corr = true_speed_correction_rpm(t, np.full_like(t, 1503.0), tt, theta, P)
    assert corr == pytest.approx(-3.0, abs=0.01)


def test_too_little_to_tell():
    t = np.arange(0.0, 0.5, 1 / 2000)
    spd = np.full_like(t, 100.0)
    assert true_speed_correction_rpm(t, spd, np.array([0.1]), np.array([0.0]), P) is None
    assert true_speed_correction_rpm(t, spd, np.array([0.1, 0.2]), np.zeros(2), 0) is None
    assert true_speed_correction_rpm(t, spd, np.array([0.1, 0.7]), np.zeros(2), P) is None


def test_true_error_of_a_rippling_servo_does_not_depend_on_the_truth_rate(tmp_path, data):
    """A 48 V, 8-pole servo with cogging (24 per turn) and flux harmonics at 1500 r/min: its
    torque ripple is at 600 Hz, a multiple of 100 Hz. From the truth's speed samples the true
    error read +6.7 and +7.2 r/min at a truth rate of 100 Hz and -4.2 and -0.6 at 97.09 Hz; from
    its angle it agrees with the measured mean error (the encoder is right) within 0.2 r/min at
    both."""
    rig = yaml.safe_load((data / "servo-48v-rig.yaml").read_text())
    rig["effects"]["flux_harmonics"] = {"emf5_rel": 0.02, "emf7_rel": 0.01}
    (tmp_path / "rig.yaml").write_text(yaml.safe_dump(rig))
    rows = {}
    for truth_hz in (100.0, 20000 / 206):
        profile = {
            "name": "servo-1500",
            "motor": str(data / "servo-48v.yaml"),
            "rig": "rig.yaml",
            "telemetry": {"truth_hz": truth_hz},
            "segments": [
                {"name": "up", "duration_s": 0.5, "speed_rpm": 1500, "ramp_rpm_s": 6000},
                {"name": "load", "duration_s": 0.5, "speed_rpm": 1500, "load_nm": 0.6},
            ],
        }
        p = tmp_path / f"p{truth_hz:.0f}.yaml"
        p.write_text(yaml.safe_dump(profile, sort_keys=False))
        out = tmp_path / f"r{truth_hz:.0f}.mcap"
        r = cli("run", p, "--no-live", "-o", out)
        assert r.returncode == 0, r.stderr
        rows[truth_hz] = summarize_log(out).segments
    for segs in rows.values():
        for s in segs:
            assert s.true_mean_error_rpm is not None
            assert abs(s.true_mean_error_rpm - s.mean_error_rpm) < 0.2, (s.name, s.__dict__)
