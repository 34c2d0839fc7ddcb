"""The run summary's generic plateau bounds (docs/analysis.md) on synthetic logs: a segment that
reaches its set-point only at its end has no plateau and is not judged on its mean error; the
plant's true speed error is the mean error corrected by the measurement's error at the truth's
instants, so a sparse truth over a transient does not make up an error the plant does not have."""

from __future__ import annotations

import numpy as np

from pmsm_hil.analysis.summary import MIN_PLATEAU_S, run_tag, summarize
from pmsm_hil.analysis.summary_text import verdict_text

TS = 5e-4  # telemetry at 2 kHz


def _log(speed_of_t, ref_of_t, t_end_s, seg_starts, truth_hz=50.0):
    t = np.arange(0.0, t_end_s, TS)
    zeros = np.zeros_like(t)
    tel = {
        "t_s": t,
        "speed_ref_rpm": ref_of_t(t),
        "speed_rpm": speed_of_t(t),
        "load_nm": zeros,
        "i_d_a": zeros,
        "i_d_ref_a": zeros,
        "i_q_a": zeros,
        "i_q_ref_a": zeros,
    }
    kinds = ["segment_start"] * len(seg_starts) + ["profile_done"]
    events = {
        "t_s": np.array([*seg_starts, t_end_s]),
        "kind": kinds,
        "arg": np.arange(len(kinds)),
        "text": [""] * len(kinds),
    }
    tt = np.arange(0.0, t_end_s, 1.0 / truth_hz)
    truth = {"t_s": tt, "speed_rpm": speed_of_t(tt)}
    return tel, events, truth


def test_a_ramp_to_the_segments_end_is_shown_but_not_judged():
    # segment 1 ramps 1500 -> 300 r/min and ends 40 ms after reaching it, the speed lagging 20 r/min
    def ref(t):
        return np.where(t < 1.0, 1500.0, np.maximum(300.0, 1500.0 - 6000.0 * (t - 1.0)))

    def speed(t):
        return ref(t) + np.where(t < 1.0, 0.0, 20.0)

    tel, events, truth = _log(speed, ref, 1.24, [0.0, 1.0])
    s = summarize(tel, events, ["hold", "down"], truth=truth)
    seg = s.segments[1]
    assert seg.plateau_s < MIN_PLATEAU_S and not seg.mean_judged
    assert abs(seg.mean_error_rpm - 20.0) < 1e-9 and seg.band_rpm == 3.0
    assert seg.mean_ok and s.ok and "within bounds" in verdict_text(s)
    # the same error on a plateau of 0.5 s is judged, and missed
    tel, events, truth = _log(speed, ref, 1.7, [0.0, 1.0])
    seg = summarize(tel, events, ["hold", "down"], truth=truth).segments[1]
    assert seg.mean_judged and not seg.mean_ok


def test_the_true_error_is_not_made_up_by_a_sparse_truth_over_a_transient():
    # the speed reaches its 600 r/min set-point at 0.42 s, inside the plateau window (0.4-0.8 s);
    # the measurement is exact, the truth sampled at 50 Hz: the plant's error is the mean error
    def ref(t):
        return np.full_like(t, 600.0)

    def speed(t):
        return np.minimum(600.0, 600.0 * t / 0.42)

    tel, events, truth = _log(speed, ref, 0.8, [0.0])
    seg = summarize(tel, events, ["start"], truth=truth).segments[0]
    assert seg.mean_error_rpm < -0.5
    assert abs(seg.true_mean_error_rpm - seg.mean_error_rpm) < 1e-9
    # a measurement that reads 2 r/min high: the plant is 2 r/min further below
    tel["speed_rpm"] = tel["speed_rpm"] + 2.0
    seg2 = summarize(tel, events, ["start"], truth=truth).segments[0]
    assert abs(seg2.true_mean_error_rpm - seg.mean_error_rpm) < 1e-9
    assert abs(seg2.mean_error_rpm - (seg.mean_error_rpm + 2.0)) < 1e-9


def test_a_log_with_no_segment_says_none_can_be_checked():
    tel, events, truth = _log(lambda t: t * 0, lambda t: t * 0, 0.01, [])
    events = {"t_s": np.array([]), "kind": [], "arg": np.array([], int), "text": []}
    s = summarize(tel, events, ["a", "b"], truth=truth)
    assert not s.segments
    assert "no segment can be checked" in verdict_text(s)
    assert "within bounds" not in verdict_text(s)


def test_the_summary_names_what_ran():
    emu = {
        "run": {"profile": "paper-a", "rig": "/x/rigs/lab-typical.yaml", "seed": "4"},
        "device": {"board": "emulator"},
    }
    assert run_tag(emu) == "profile paper-a, rig lab-typical, seed 4"
    emu["run"]["motor"] = "paper-a-ipmsm-commissioned"  # another motor file: it is said
    assert (
        run_tag(emu) == "profile paper-a, motor paper-a-ipmsm-commissioned, rig lab-typical, seed 4"
    )
    rig = {"run": {"profile": "paper-a", "rig": "", "seed": ""}, "device": {"board": "f28335"}}
    assert run_tag(rig) == "profile paper-a, board f28335"
    assert run_tag({}) == ""
    # the current controllers in the order the segments first run them, and an estimator's name
    emu["run"].update(current_ctrl="mpcc|foc|mpcc", angle_src="encoder")
    assert run_tag(emu).startswith("profile paper-a, MPCC then FOC, motor ")
    emu["run"].update(current_ctrl="foc|foc", angle_src="mras")
    assert run_tag(emu).startswith("profile paper-a, FOC, sensorless (mras), motor ")


def test_a_runs_log_records_each_segments_current_controller(tmp_path, data):
    """The log's run metadata says which controller ran each segment and the angle source (the
    summary's title names them: an MPCC run and a FOC run were told apart by file name only)."""
    from emu_helpers import run_inproc

    from pmsm_hil.log.reader import read_log

    text = (
        (data / "short.yaml")
        .read_text()
        .replace("../../profiles/", f"{data.parent.parent}/profiles/")
    )
    text = text.replace('{name: "load on", ', '{name: "load on", current_ctrl: foc, ')
    prof = tmp_path / "p.yaml"
    prof.write_text(text)
    run_inproc(prof, tmp_path / "r.mcap")
    meta = read_log(tmp_path / "r.mcap", topics=[]).metadata
    assert meta["run"]["current_ctrl"] == "mpcc|foc|foc" and meta["run"]["angle_src"] == "encoder"
    assert run_tag(meta).startswith("profile short, MPCC then FOC, motor paper-a-ipmsm, rig ")


def test_a_fault_that_ends_the_run_is_counted_and_named_in_every_verdict(tmp_path):
    """An over-speed trip at the instant the log's last segment ends (the run stops there): the
    segment counts it, and the verdict names it instead of "segments seen are within bounds";
    the report's page says what the console says."""
    from pmsm_hil.analysis.report_html import summary_html

    def ref(t):
        return np.full_like(t, 1500.0)

    tel, events, truth = _log(ref, ref, 1.0, [0.0])
    events = {  # the trip and the stop at the end, no profile_done
        "t_s": np.array([0.0, 0.9995, 0.9995]),
        "kind": ["segment_start", "fault", "stopped"],
        "arg": np.arange(3),
        "text": ["", "fault: over_speed", "fault"],
    }
    s = summarize(tel, events, ["step up", "hold"], truth=truth)
    assert s.segments[-1].faults == 1
    v = verdict_text(s)
    assert "INCOMPLETE" in v and "1 fault: 1.000 s fault: over_speed" in v
    assert "within bounds" not in v.split("):")[0]
    page = summary_html(s)
    assert "1 fault: 1.000 s fault: over_speed" in page and "plateau bounds missed" not in page
    assert "1 segment," in page


def test_a_recovery_that_never_comes_is_never_and_the_json_is_valid():
    import json
    import subprocess
    import sys

    from pmsm_hil.gap.report import jsonable

    d = {"segments": [{"recovery_s": float("inf"), "mean_error_rpm": float("nan")}], "n": 1}
    text = json.dumps(jsonable(d), allow_nan=False)
    assert json.loads(text) == {"segments": [{"recovery_s": None, "mean_error_rpm": None}], "n": 1}
    r = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", "run", "paper-a", "--seed", "4294967297"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and "give a whole number 0..2147483647" in r.stderr
