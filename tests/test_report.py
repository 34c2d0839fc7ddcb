"""`pmsm-hil report`: PNGs and one self-contained HTML page for a run, panels without data skipped,
bad input refused with exit 2."""

from __future__ import annotations

import base64
import os
import re
import struct

import numpy as np
import pytest
from emu_helpers import run_inproc

from pmsm_hil.analysis.report import PANELS, ReportError, build_report
from pmsm_hil.cli.main import main
from pmsm_hil.log.writer import LogWriter

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == PNG_MAGIC
    return struct.unpack(">II", data[16:24])


@pytest.fixture(scope="module")
def short_log(tmp_path_factory, request):
    out = tmp_path_factory.mktemp("report") / "short.mcap"
    run_inproc(
        request.config.rootpath / "tests" / "data" / "short.yaml",
        out,
        seed=4,
        rig=str(request.config.rootpath / "profiles" / "rigs" / "lab-typical.yaml"),
        rig_name="profiles/rigs/lab-typical.yaml",
    )
    return out


def test_report_writes_the_panels_and_one_self_contained_page(short_log, tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["report", str(short_log), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    expected = {"speed", "currents", "voltages", "parameters", "capture"}
    for key in expected:
        png = out / f"{key}.png"
        assert png.is_file(), key
        w, h = png_size(png.read_bytes())
        assert 800 <= w <= 2000 and 300 <= h <= 2000, (key, w, h)
        assert str(png) in printed
    html = (out / "report.html").read_text()
    # the page names the run (profile, rig, seed) and links every drawn panel
    assert "short · rig lab-typical · seed 4" in html
    for key in expected:
        assert f'href="#panel-{key}"' in html and f'id="panel-{key}"' in html
    # images are embedded, not linked: every <img> is a data URI holding a valid PNG
    imgs = re.findall(r'<img alt="[^"]*" src="data:image/png;base64,([^"]+)"', html)
    assert len(imgs) == len(expected)
    for b in imgs:
        png_size(base64.b64decode(b))
    assert 'src="http' not in html and '.png"' not in html
    # no sensorless estimator ran: that panel is skipped, with the reason on the page
    assert not (out / "estimation_error.png").exists()
    assert 'id="skipped-estimation_error"' in html and "encoder" in html
    # the per-segment summary: the three segments of short.yaml
    for name in ("up to 500 r/min", "load on", "load off"):
        assert f"{name}</td>" in html
    assert "No estimator ran" in html
    # a complete run carries no warning note
    assert 'class="note"' not in html


def test_estimators_give_the_identification_table_and_the_error_panel(tmp_path):
    """A log written directly: params of three estimators against a truth, and an estimated
    angle that differs from the encoder's."""
    log = tmp_path / "synthetic.mcap"
    meta = {
        "run": {
            "profile": "synthetic",
            "rig": "rigs/bench-x.yaml",
            "seed": "9",
            "segment_names": "a|b",
        },
        "device": {"board": "emulator"},
    }
    t = np.arange(0, 2.0, 5e-4)
    n = len(t)
    with LogWriter(log, meta) as w:
        theta = (t * 2 * np.pi * 30) % (2 * np.pi)
        w.write_many(
            "/pmsm/telemetry",
            {
                "t_s": t,
                "speed_ref_rpm": np.full(n, 450.0),
                "speed_rpm": np.full(n, 450.0),
                "speed_est_rpm": 450.0 + np.sin(t),
                "theta_e_rad": theta,
                "theta_e_est_rad": (theta + 0.05) % (2 * np.pi),
                "i_d_a": np.zeros(n),
                "i_q_a": np.ones(n),
                "i_d_ref_a": np.zeros(n),
                "i_q_ref_a": np.ones(n),
                "u_d_v": np.zeros(n),
                "u_q_v": np.full(n, 50.0),
                "load_nm": np.zeros(n),
            },
        )
        tp = np.arange(0, 2.0, 0.01)
        for est, k in (("rls", 1.05), ("adaline", 1.01), ("nlms_adaline", 1.0)):
            for ti in tp:
                w.write(
                    "/pmsm/params",
                    float(ti),
                    {
                        "estimator": est,
                        "l_d_h": 5e-3 * k,
                        "l_q_h": 12e-3 * k,
                        "psi_f_wb": 0.18 * k,
                        "r_s_ohm": 0.9 * k,
                        "converged": True,
                    },
                )
        w.write_many(
            "/sim/truth",
            {
                "t_s": tp,
                "l_d_h": np.full(len(tp), 5e-3),
                "l_q_h": np.full(len(tp), 12e-3),
                "psi_f_wb": np.full(len(tp), 0.18),
                "r_s_ohm": np.full(len(tp), 0.9),
                "speed_rpm": np.full(len(tp), 450.0),
            },
        )
        for i, ti in enumerate((0.0, 1.0)):
            w.write("/pmsm/events", ti, {"kind": "segment_start", "code": 1, "arg": i, "text": ""})
        w.write("/pmsm/events", 0.3, {"kind": "polarity", "code": 0, "arg": 0, "text": "kept"})
        w.write("/pmsm/events", 1.5, {"kind": "fault", "code": 0, "arg": 0, "text": "lost_lock"})
    rep = build_report(log, tmp_path / "out")
    assert set(rep.pngs) == {"speed", "currents", "voltages", "parameters", "estimation_error"}
    # the angle error's RMS in rad beside the degrees, the polarity result and the fault marked
    from pmsm_hil.analysis.report_context import run_context
    from pmsm_hil.analysis.report_signals import estimation_error
    from pmsm_hil.log.reader import read_log

    fig = estimation_error(run_context(read_log(log), log))
    ax = fig.axes[0]
    labels = ax.get_legend_handles_labels()[1]
    assert "θe,est − θe\n(RMS 0.0500 rad = 2.86°)" in labels, labels
    assert labels.count("polarity test") == 1 and labels.count("fault") == 1
    xs = sorted(
        float(ln.get_xdata()[0])
        for ln in ax.get_lines()
        if ln.get_linestyle() in ("-", "--")
        and len(ln.get_xdata()) == 2
        and ln.get_xdata()[0] == ln.get_xdata()[1]
    )
    assert 0.3 in xs and 1.5 in xs, xs
    assert set(rep.skipped) == {"capture"}
    html = rep.html.read_text()
    assert "synthetic · rig bench-x · seed 9" in html
    # identification table: rls is 5 % off (red), nlms_adaline exact
    assert "+5.00 %" in html and "+0.00 %" in html
    assert "nlms_adaline final" in html
    assert 'id="skipped-capture"' in html


def test_every_panel_has_a_title_and_a_caption():
    keys = [p[0] for p in PANELS]
    assert keys == ["speed", "currents", "voltages", "parameters", "estimation_error", "capture"]
    assert all(p[1] and p[3] for p in PANELS)


def test_bad_input_exits_2_without_traceback(tmp_path, short_log, capsys):
    missing = tmp_path / "nope.mcap"
    assert main(["report", str(missing)]) == 2
    err = capsys.readouterr().err
    assert "nope.mcap: no such file" in err and "Traceback" not in err
    for cmd in (["report"], ["analyze"], ["log", "recover"]):  # a folder is not "no such file"
        assert main([*cmd, str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert f"{tmp_path}: is a directory, not a log" in err and "Traceback" not in err, cmd

    not_mcap = tmp_path / "text.mcap"
    not_mcap.write_text("hello\n")
    assert main(["report", str(not_mcap)]) == 2
    assert "not an MCAP file" in capsys.readouterr().err
    cut = tmp_path / "cut-in-magic.mcap"  # killed before the first record: not "not MCAP"
    cut.write_bytes(short_log.read_bytes()[:5])
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    for cmd in (["report"], ["analyze"], ["log", "recover"]):
        assert main([*cmd, str(cut)]) == 2
        err = capsys.readouterr().err
        assert "cut off after 5 octets, inside the MCAP magic" in err, cmd
        assert main([*cmd, ""]) == 2  # not taken for the working directory
        assert "'': an empty name; give the log's path" in capsys.readouterr().err, cmd
        assert main([*cmd, str(fifo)]) == 2  # neither "empty" nor a read that waits for ever
        assert f"{fifo}: not a regular file (a pipe or a device)" in capsys.readouterr().err, cmd

    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["report", str(short_log), "-o", str(blocker / "sub")]) == 2
    err = capsys.readouterr().err
    assert f"-o {blocker / 'sub'}: {blocker} is a file, not a folder" in err
    assert "Traceback" not in err
    assert main(["report", str(short_log), "-o", str(blocker)]) == 2  # said as such, not EEXIST
    err = " ".join(capsys.readouterr().err.split())
    assert f"-o {blocker}: is a file; give a folder for the PNGs and report.html" in err

    empty = tmp_path / "empty.mcap"
    LogWriter(empty, {}).close()
    for cmd in ("report", "analyze"):  # the two say the same of a log with nothing to judge
        assert main([cmd, str(empty)]) == 2
        assert "no telemetry in the log" in capsys.readouterr().err
        zero = tmp_path / "zero.mcap"
        zero.write_bytes(b"")
        assert main([cmd, str(zero)]) == 2
        assert "zero.mcap: the file is empty (0 octets)" in capsys.readouterr().err


def test_an_imported_record_or_a_commissioning_run_is_sent_where_it_is_read(tmp_path, capsys):
    """analyze and report judge profile runs: an imported control-rate record goes to `gap`, a
    commissioning run to its motor file (both once passed as an incomplete run of 0 segments)."""
    for topic, what in (
        ("/pmsm/control_rate", "diagnose it with `pmsm-hil gap LOG`"),
        ("/pmsm/commission", "its results are in the commissioned motor file"),
    ):
        from pmsm_hil.gap.record import GAP_TOPICS

        log = tmp_path / f"{topic.rsplit('/', 1)[-1]}.mcap"
        w = LogWriter(log, {}, topics=GAP_TOPICS)
        w.write(topic, 0.0, {})
        if topic == "/pmsm/commission":  # a commissioning run has telemetry too
            w.write("/pmsm/telemetry", 0.0, {})
        w.close()
        for cmd in ("analyze", "report"):
            if cmd == "analyze" and topic == "/pmsm/commission":
                continue  # analyze shows a commissioning run's steps (below)
            assert main([cmd, str(log)]) == 2
            assert what in capsys.readouterr().err, cmd
    # analyze of a commissioning run: its steps and results, as `commission` printed them
    w = LogWriter(tmp_path / "comm.mcap", {})
    w.write("/pmsm/telemetry", 0.0, {})
    row = {"step": "r_s", "status": "ok", "value_0": 0.9, "spread_0": 1e-4}
    w.write("/pmsm/commission", 1.0, row)
    w.write("/pmsm/commission", 2.0, {"step": "psi_f", "status": "not_repeatable"})
    w.close()
    assert main(["analyze", str(tmp_path / "comm.mcap")]) == 1  # a step failed
    out = capsys.readouterr().out
    assert "a commissioning run (pmsm-hil commission), 2 steps logged" in out
    assert "stator resistance by injection: ok" in out and "r_s_ohm" in out and "0.9 ohm" in out
    assert "psi_f by a short spin: not_repeatable" in out


def test_default_directory_is_beside_the_log(short_log, tmp_path):
    import shutil

    log = tmp_path / "run1.mcap"
    shutil.copy(short_log, log)
    rep = build_report(log)
    assert rep.out_dir == tmp_path / "run1-report"
    assert rep.html.is_file()


def test_truncated_log_is_reported_as_such(short_log, tmp_path):
    data = short_log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 6 // 10])
    rep = build_report(cut, tmp_path / "out")
    html = rep.html.read_text()
    assert "not finalised" in html
    assert "speed" in rep.pngs  # what was recovered is plotted
    assert "log recover" not in html  # no journal beside it: nothing to point to
    (tmp_path / "cut.mcap.journal").write_bytes(b"")
    html = build_report(cut, tmp_path / "out").html.read_text()
    assert f"cut.mcap.journal is beside it: `pmsm-hil log recover {cut}`" in html
    empty = tmp_path / "empty-cut.mcap"  # cut before its first chunk: the error points there too
    empty.write_bytes(data[:200])
    (tmp_path / "empty-cut.mcap.journal").write_bytes(b"")
    with pytest.raises(ReportError, match="log recover"):
        build_report(empty, tmp_path / "out2")


def test_analyze_points_to_the_journal_beside_a_cut_log(short_log, tmp_path, capsys):
    data = short_log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 6 // 10])
    main(["analyze", str(cut)])
    assert "log recover" not in capsys.readouterr().out  # no journal: nothing to point to
    (tmp_path / "cut.mcap.journal").write_bytes(b"")
    main(["analyze", str(cut)])
    assert f"cut.mcap.journal is beside it: `pmsm-hil log recover {cut}`" in capsys.readouterr().out


def test_a_stopped_run_says_it_did_not_reach_the_end(data, tmp_path):
    out = tmp_path / "stopped.mcap"
    run_inproc(data / "long.yaml", out, stop_after_s=1.2)
    html = build_report(out, tmp_path / "out").html.read_text()
    assert "did not reach the profile&#x27;s end" in html and "host stop" in html
    assert "not finalised" not in html


def test_the_capture_panel_says_what_triggered_it(short_log, data, tmp_path):
    """The buffer records from the start: a run without a `capture: true` segment or a fault
    still uploads one, its last moments; the panel says so instead of passing it off as chosen."""
    from pmsm_hil.analysis.report_capture import capture
    from pmsm_hil.analysis.report_context import run_context
    from pmsm_hil.log.reader import read_log

    def title(path) -> str:
        return capture(run_context(read_log(path), path)).get_suptitle()

    assert "\ntriggered at segment 1 'load on'; MPCC switching frequency" in title(short_log)
    out = tmp_path / "untriggered.mcap"
    run_inproc(data / "long.yaml", out, stop_after_s=0.3)
    assert "\nnot triggered: the run's last 51.2 ms (no segment has capture: true);" in title(out)


def test_the_capture_panel_gives_the_mpccs_switching_frequency(short_log):
    """Per leg: the upper switch's changes over the capture, half of them a period, per second;
    FOC's samples (NaN) left out."""
    import re

    from pmsm_hil.analysis.report_capture import capture, switching_hz
    from pmsm_hil.analysis.report_context import run_context
    from pmsm_hil.log.reader import read_log

    ts_s = 50e-6
    toggling = np.tile([0.0, 1.0], 50)  # a change every period: one switching period in two
    assert switching_hz({"a": toggling}, ts_s)["a"] == pytest.approx(1 / (2 * ts_s))
    half = toggling.copy()
    half[:50] = np.nan  # FOC ran there: only the known pairs count
    assert switching_hz({"a": half}, ts_s)["a"] == pytest.approx(1 / (2 * ts_s))
    assert switching_hz({"a": np.full(10, np.nan)}, ts_s) == {}

    log = read_log(short_log)
    cap = log.topic("/pmsm/capture")
    m = re.search(
        r"MPCC switching frequency per leg \(mean over the capture\): a ([0-9.]+), "
        r"b ([0-9.]+), c ([0-9.]+) kHz",
        capture(run_context(log, short_log)).get_suptitle(),
    )
    assert m
    for ph, got_khz in zip("abc", m.groups(), strict=True):
        s = np.asarray(cap[f"s_{ph}"], float)
        t = np.asarray(cap["t_s"], float)
        want = np.count_nonzero(np.diff(s)) / 2 / ((len(s) - 1) * np.median(np.diff(t)))
        assert float(got_khz) == pytest.approx(want / 1e3, abs=0.006)
        assert 0.5 < float(got_khz) < 10.0  # between a switch every 20 periods and every period


def test_a_long_series_is_drawn_from_each_slices_extremes_in_time_order():
    from pmsm_hil.analysis.report_style import envelope

    rng = np.random.default_rng(3)
    t = np.arange(10_037) * 5e-4
    y = rng.normal(size=len(t))
    y[4000:4100] = np.nan  # slice 40 entirely: a gap, as the full line shows
    y[4150] = np.nan  # one sample of slice 41: its extremes are the finite ones
    slices, k = 100, len(t) // 100
    te, ye = envelope(t, y, slices=slices)
    assert len(te) == 2 * slices + (len(t) - slices * k)
    assert np.all(np.diff(te) >= 0)
    idx = np.searchsorted(t, te)
    np.testing.assert_array_equal(t[idx], te)  # every point is a sample, at its own time
    np.testing.assert_array_equal(y[idx], ye)
    for i in range(slices):
        run, got = y[i * k : (i + 1) * k], ye[2 * i : 2 * i + 2]
        if np.all(np.isnan(run)):
            assert np.isnan(got).all()
        else:
            assert np.nanmin(run) == got.min() and np.nanmax(run) == got.max(), i
    np.testing.assert_array_equal(ye[2 * slices :], y[slices * k :])  # the remainder as is
    finite = np.nan_to_num(y)  # no NaN: the same extremes (taken without a copy)
    _, yf = envelope(t, finite, slices=slices)
    runs = finite[: slices * k].reshape(slices, k)
    np.testing.assert_array_equal(
        yf[: 2 * slices : 2],
        np.where(runs.argmin(axis=1) < runs.argmax(axis=1), runs.min(axis=1), runs.max(axis=1)),
    )
    np.testing.assert_array_equal(
        np.sort(yf[: 2 * slices].reshape(slices, 2), axis=1),
        np.stack([runs.min(axis=1), runs.max(axis=1)], axis=1),
    )
    ts, ys = envelope(t[:150], y[:150], slices=slices)  # short: unchanged
    np.testing.assert_array_equal(ts, t[:150])
    np.testing.assert_array_equal(ys, y[:150])


def test_a_long_band_covers_every_samples_band_without_crossing_itself():
    from pmsm_hil.analysis.report_style import band

    rng = np.random.default_rng(7)
    t = np.arange(10_037) * 1e-2
    v = 2.0 + 0.3 * np.sin(t) + rng.normal(scale=0.05, size=len(t))
    lo, hi = v * 0.98, v * 1.02
    lo[4000:4100] = hi[4000:4100] = np.nan  # slice 40 entirely: a gap
    slices, k = 100, len(t) // 100
    bt, blo, bhi = band(t, lo, hi, slices=slices)
    assert len(bt) == 2 * slices + (len(t) - slices * k)
    assert np.all(np.diff(bt) >= 0)
    assert bt[0] == t[0] and bt[-1] == t[-1]
    # the band at each sample's time (the step it falls in) holds that sample's band
    step = np.minimum(np.arange(len(t)) // k, slices)
    at_lo = np.where(step < slices, blo[2 * np.minimum(step, slices - 1)], np.nan)
    at_hi = np.where(step < slices, bhi[2 * np.minimum(step, slices - 1)], np.nan)
    body = (step < slices) & np.isfinite(lo)
    assert np.all(at_lo[body] <= lo[body]) and np.all(at_hi[body] >= hi[body])
    for i in (0, 17, 99):  # as tight as the samples: each step is its run's extremes
        assert blo[2 * i] == np.nanmin(lo[i * k : (i + 1) * k])
        assert bhi[2 * i + 1] == np.nanmax(hi[i * k : (i + 1) * k])
    assert np.isnan(blo[80]) and np.isnan(bhi[81])
    np.testing.assert_array_equal(blo[2 * slices :], lo[slices * k :])  # the remainder as is
    short = band(t[:150], lo[:150], hi[:150], slices=slices)
    for got, want in zip(short, (t[:150], lo[:150], hi[:150]), strict=True):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("block", [None, 1000, 41])
def test_the_voltage_panels_mean_and_the_angle_errors_wrap(block, monkeypatch):
    """The 20 ms mean is np.convolve's centred window (zeros beyond the ends) for odd and even
    windows, also where it is computed a block at a time (blocks of 1000 and of 41 samples, as
    short as a window: each block's edges take their neighbours' samples); the angle error is
    brought into [-pi, pi] by whole turns."""
    from pmsm_hil.analysis import report_signals
    from pmsm_hil.analysis.report_signals import _mean, _wrap

    if block is not None:
        monkeypatch.setattr(report_signals, "BLOCK", block)
    rng = np.random.default_rng(5)
    x = rng.normal(80.0, 40.0, 5003)
    for step_s in (5e-4, 4.9e-4, 1e-3, 2e-3):  # windows of 40, 41, 20 and 10 samples
        t = np.arange(len(x)) * step_s
        n = max(1, round(0.02 / step_s))
        np.testing.assert_allclose(
            _mean(t, x, 0.02), np.convolve(x, np.ones(n) / n, mode="same"), atol=1e-9
        )
    t = np.arange(len(x)) * 0.05  # a window of one sample: the series as it is
    np.testing.assert_array_equal(_mean(t, x, 0.02), x)
    a = rng.uniform(-40.0, 40.0, 10_000)
    w = _wrap(a.copy())
    assert np.all(np.abs(w) <= np.pi)
    turns = (a - w) / (2.0 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-9)


def test_report_reads_the_log_once_and_draws_long_series_from_their_envelope(
    short_log, tmp_path, monkeypatch
):
    """The panels, the summary and the identification table come from one read of the file;
    a series longer than the envelope's slices is drawn from its extremes (the figure's lines
    have at most two points per slice and show the data's full range)."""
    from pmsm_hil.analysis import report_signals, report_style
    from pmsm_hil.analysis.report_context import run_context
    from pmsm_hil.log import parse
    from pmsm_hil.log.reader import read_log

    reads = []
    original = parse._Parser.run

    def counted(self):
        reads.append(1)
        original(self)

    monkeypatch.setattr(parse._Parser, "run", counted)
    build_report(short_log, tmp_path / "rep")
    assert len(reads) == 1

    slices = 200
    monkeypatch.setattr(report_style, "ENVELOPE_SLICES", slices)
    log = read_log(short_log)
    tel = log.topic("/pmsm/telemetry")
    assert len(tel["t_s"]) > 4 * slices
    fig = report_signals.currents(run_context(log, short_log))
    lines = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_label() == "i_d measured"]
    assert len(lines) == 1
    x, y = lines[0].get_data()
    assert len(x) <= 3 * slices
    assert y.min() == tel["i_d_a"].min() and y.max() == tel["i_d_a"].max()
    report_style.close(fig)


def test_the_reports_read_draws_what_a_read_of_everything_draws(short_log, tmp_path):
    """The report decodes only the fields its panels, context and tables declare (REPORT_TOPICS):
    every panel, drawn from that read, is the same image as drawn from the whole log, on a run
    with capture and truth and on a synthetic log with estimators and an angle estimator."""
    from pmsm_hil.analysis.report import REPORT_TOPICS, _png
    from pmsm_hil.analysis.report_context import run_context
    from pmsm_hil.log.reader import read_log
    from pmsm_hil.recorder import TELEMETRY_FIELDS

    synthetic = tmp_path / "est.mcap"
    t = np.arange(0.0, 1.0, 5e-4)
    n = len(t)
    with LogWriter(synthetic, {"run": {"profile": "est", "segment_names": "a"}}) as w:
        theta = (t * 2 * np.pi * 30) % (2 * np.pi)
        cols = {k: np.sin(t * (i + 1)) for i, k in enumerate(TELEMETRY_FIELDS)}
        cols.update(t_s=t, theta_e_rad=theta, theta_e_est_rad=(theta + 0.05) % (2 * np.pi))
        w.write_many("/pmsm/telemetry", cols)
        w.write_many("/sim/truth", {"t_s": t[::50], "speed_rpm": np.full(n // 50, 450.0)})
        for i, ti in enumerate(t[::20]):
            w.write(
                "/pmsm/estimator",
                float(ti),
                {"estimator": "ripple_pll", "locked": i % 7 != 0, "in_loop": True},
            )
            w.write(
                "/pmsm/params",
                float(ti),
                {"estimator": "rls", "l_d_h": 5e-3, "l_q_h": 1e-2, "psi_f_wb": 0.2, "r_s_ohm": 1.0},
            )
        w.write("/pmsm/events", 0.0, {"kind": "segment_start", "arg": 0, "text": ""})
    drawn = 0
    for path in (short_log, synthetic):
        whole, part = read_log(path), read_log(path, topics=REPORT_TOPICS)
        # something is left out (the truth's other fields), and the context is the same
        assert set(part.topic("/sim/truth")) < set(whole.topic("/sim/truth"))
        a, b = run_context(whole, path), run_context(part, path)
        assert (a.tag, a.segments, a.notes) == (b.tag, b.segments, b.notes)
        for key, _, fn, _ in PANELS:
            fa, fb = fn(a), fn(b)
            assert isinstance(fa, str) == isinstance(fb, str), key
            if isinstance(fa, str):
                assert fa == fb, key
            else:
                assert _png(fa) == _png(fb), (path.name, key)
                drawn += 1
    assert drawn == 10  # five each: the capture on the run, the estimation error (and the
    # parameters against a truth that has none of them) on the synthetic log


@pytest.mark.parametrize("second", [None, "mpcc"])
def test_the_capture_panel_leaves_out_switch_states_where_foc_ran(data, tmp_path, second):
    """The firmware records switch states for the MPCC only (0 under FOC): the panel must not
    draw a FOC run's legs as off with zero duty while its currents flow."""
    from pmsm_hil.analysis.report_capture import FOC_NOTE, capture
    from pmsm_hil.analysis.report_context import run_context
    from pmsm_hil.log.reader import read_log

    text = (data / "short.yaml").read_text()
    text = text.replace("../../profiles/", str(data.parent.parent / "profiles") + "/")
    text = text.replace("segments:", "control: {current_ctrl: foc}\nsegments:")
    if second:  # the capture's pre-trigger samples under FOC, the rest under the MPCC
        text = text.replace("capture: true}", f"capture: true, current_ctrl: {second}}}")
    prof = tmp_path / "foc.yaml"
    prof.write_text(text)
    out = tmp_path / "foc.mcap"
    run_inproc(prof, out)
    fig = capture(run_context(read_log(out), out))
    assert FOC_NOTE in fig.get_suptitle()
    duty_ax, zoom_ax = fig.axes[1], fig.axes[3]
    duty = np.concatenate([line.get_ydata() for line in duty_ax.get_lines()])
    zoom = np.concatenate([line.get_ydata() for line in zoom_ax.get_lines()])
    assert np.isnan(zoom).all()  # the first 60 periods are before the trigger: FOC
    if second is None:
        assert np.isnan(duty).all()
        assert "switching frequency" not in fig.get_suptitle()  # no MPCC sample
        assert FOC_NOTE in [t.get_text() for t in duty_ax.texts]
    else:
        drawn = duty[~np.isnan(duty)]
        assert drawn.size and 0.1 < drawn.mean() < 0.9  # the MPCC's duty, not FOC's zeros
