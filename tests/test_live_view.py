"""The live view shows what an engineer tuning a drive looks at, and --no-live prints plain lines."""

from __future__ import annotations

import io

import pytest
from rich.console import Console

from pmsm_hil.cli.live import FLAGS_LEGEND, LiveView, PlainProgress, make_observer, render
from pmsm_hil.recorder import LiveState


def sample_state() -> LiveState:
    live = LiveState(
        t_s=12.5,
        total_s=32.5,
        segment=4,
        state="running",
        frames=25000,
        octets=1_000_000,
        bad_frames=3,
        seq_gaps=2,
        tx_dropped=0,
    )
    live.telemetry = {
        "speed_ref_rpm": 240.0,
        "speed_rpm": 239.7,
        "i_d_a": -0.81,
        "i_q_a": 4.52,
        "i_d_ref_a": -0.76,
        "i_q_ref_a": 4.50,
        "load_nm": 5.0,
        "theta_e_rad": 1.234,
    }
    live.params["nominal"] = {
        "l_d_h": 0.005,
        "l_q_h": 0.012,
        "psi_f_wb": 0.18,
        "r_s_ohm": 0.9,
        "feeds_predictor": True,
    }
    live.truth = {"l_d_h": 0.005, "l_q_h": 0.012, "psi_f_wb": 0.18, "r_s_ohm": 0.9}
    live.events.append((12.0, "segment_start", 4, "segment 4 240 r/min load on"))
    return live


def test_live_panel_shows_progress_signals_parameters_and_link():
    con = Console(file=io.StringIO(), width=160, color_system=None)
    con.print(render(sample_state(), "paper-a on emulator", 921600.0, [f"s{i}" for i in range(13)]))
    text = con.file.getvalue()
    assert "12.50 / 32.50 s" in text
    assert "running" in text and "segment 4 s4" in text
    assert "240.0" in text and "239.7" in text  # speed ref / measured
    assert "4.50" in text and "4.52" in text  # i_q ref / measured
    assert "12.000" in text  # L_q in mH
    assert "truth" in text
    # link use in device time: 1e6 octets * 10 bits over 12.5 s at 921.6 kbit/s = 86.8 %
    assert "86.8 %" in text
    assert "segment 4 240 r/min load on" in text


def test_plain_progress_prints_a_line_per_period():
    out = io.StringIO()
    p = PlainProgress(stream=out, period_s=0.0)
    p.update(sample_state())
    p.message("uploading capture")
    lines = out.getvalue().splitlines()
    assert lines[0] == "  12.000 s  segment 4 240 r/min load on"  # the event before the line
    assert (
        lines[1].startswith("t=  12.50/32.50 s")
        and "speed ref/meas   240.0/  239.7 r/min" in lines[1]
    )
    assert lines[2] == "uploading capture"


def test_plain_progress_prints_each_device_event_once():
    # a pipe (CI) sees the polarity test's result or a fault when it happens, not only at the end
    out = io.StringIO()
    live = sample_state()
    with PlainProgress(stream=out, period_s=0.0) as p:
        p.update(live)
        live.events.append((12.3, "host", 0, "interrupted by SIGINT: stop sent"))
        live.events.append((12.4, "polarity", 1, "polarity: kept"))
        p.update(live)
        live.events.append((12.5, "stopped", 0, "stopped: host stop"))
        p.period_s = 1e9  # no further line: the last event comes before the next message
        p.update(live)
        p.message("uploading capture")
    lines = out.getvalue().splitlines()
    events = [ln for ln in lines[:-1] if not ln.startswith(("t=", "    estimator"))]
    assert events == [
        "  12.000 s  segment 4 240 r/min load on",
        "  12.400 s  polarity: kept",
        "  12.500 s  stopped: host stop",
    ]  # each once, in order; the host's own events are printed by the host as messages
    assert lines[-2:] == ["  12.500 s  stopped: host stop", "uploading capture"]


def identifying_state() -> LiveState:
    live = sample_state()
    for name, k, flags in (
        ("rls", 1.02, {"excited": True}),
        ("adaline", 0.99, {"excited": True, "converged": True}),
        ("nlms_adaline", 1.001, {"excited": True, "converged": True, "feeds_predictor": True}),
    ):
        live.params[name] = {
            "l_d_h": 0.005 * k,
            "l_q_h": 0.012 * k,
            "psi_f_wb": 0.18 * k,
            "r_s_ohm": 0.9 * k,
            **flags,
        }
    live.params["nominal"]["feeds_predictor"] = False
    for i in range(6):
        live.events.append((12.1 + 0.1 * i, "host", 0, f"event number {i}"))
    return live


def draw(live: LiveState, width: int, height: int) -> str:
    con = Console(file=io.StringIO(), width=width, height=height, color_system=None)
    con.print(
        render(
            live,
            "paper-a-identify on emulator (serial 921600)",
            921600.0,
            [f"s{i}" for i in range(13)],
        )
    )
    return con.file.getvalue()


def test_live_panel_fits_80_by_24_without_ellipsis():
    text = draw(identifying_state(), 80, 24)
    lines = text.splitlines()
    assert len(lines) <= 24
    assert all(len(line) <= 80 for line in lines)
    assert "…" not in text
    # the key values are all there: progress, state, speed, currents, every estimator, link use
    assert "12.50 / 32.50 s" in text and "running" in text and "segment 4 s4" in text
    assert "240.0" in text and "239.7" in text and "4.50" in text and "4.52" in text
    assert "nlms_adaline * ec" in text and "adaline ec" in text and "rls e-" in text
    assert "truth" in text and "86.8 %" in text
    # ... and the flags are explained on screen
    assert "* feeds predictor" in text and "c converged" in text and "e excited" in text
    # the most recent event is shown, older ones make room
    assert "event number 5" in text


def test_live_panel_at_60_by_24_keeps_every_estimator_and_the_truth():
    # a narrow terminal stacks the tables: the link then takes one line, not a six-row table, so
    # that the parameters (the estimator feeding the predictor last) are still on the screen
    text = draw(identifying_state(), 60, 24)
    lines = text.splitlines()
    assert len(lines) <= 23  # rich.Live keeps one line for its cursor
    assert all(len(line) <= 60 for line in lines)
    assert "nlms_adaline * ec" in text and "truth" in text and "c converged" in text
    assert "25000 frames" in text and "86.8 %" in text and "3 bad" in text and "2 gaps" in text


def test_120_columns_show_the_three_tables_side_by_side():
    (line,) = [ln for ln in draw(sample_state(), 120, 40).splitlines() if "signals" in ln]
    assert "parameters" in line and "link" in line


def sensorless_state() -> LiveState:
    live = sample_state()
    live.telemetry.update(speed_est_rpm=241.3, theta_e_est_rad=1.229)
    live.estimator = {
        "estimator": "ripple_pll",
        "locked": True,
        "in_loop": True,
        "confidence": 0.97,
        "theta_err_rad": -0.005,
        "speed_err_rpm": 1.6,
    }
    return live


@pytest.mark.parametrize("width,height", [(60, 24), (80, 24), (120, 40)])
def test_sensorless_run_shows_the_estimated_speed_and_angle_beside_the_encoder(width, height):
    text = draw(sensorless_state(), width, height)
    (head,) = [ln for ln in text.splitlines() if "measured" in ln]
    assert "estimate" in head
    (speed,) = [ln for ln in text.splitlines() if "speed r/min" in ln]
    assert "239.7" in speed and "241.3" in speed  # encoder, estimate
    (angle,) = [ln for ln in text.splitlines() if "θe rad" in ln]
    assert "1.234" in angle and "1.229" in angle
    assert "ripple_pll" in text and "theta_err" in text and "-0.0050 rad" in text
    # without an estimator there is no estimate column (the angle slot's values are the encoder's)
    assert "estimate" not in draw(sample_state(), width, height)


@pytest.mark.parametrize("width,height", [(60, 40), (100, 30), (200, 50)])
def test_live_panel_never_truncates_with_ellipsis(width, height):
    text = draw(identifying_state(), width, height)
    assert "…" not in text
    assert all(len(line) <= width for line in text.splitlines())
    assert "nlms_adaline" in text and "239.7" in text


def test_wide_terminal_shows_errors_against_truth_and_the_full_legend():
    text = draw(identifying_state(), 200, 50)
    assert "+2.0%" in text  # rls L_d against the truth
    assert FLAGS_LEGEND in text


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_piped_output_gets_plain_lines():
    out = io.StringIO()  # not a terminal
    obs = make_observer(False, "short on emulator", 921600.0, ["a"], stream=out)
    assert isinstance(obs, PlainProgress)
    obs.period_s = 0.0
    with obs:
        obs.update(sample_state())
    assert out.getvalue().splitlines()[1].startswith("t=  12.50/32.50 s")
    assert isinstance(make_observer(True, "x", 1.0, [], stream=out), PlainProgress)
    assert isinstance(make_observer(False, "x", 1.0, [], stream=FakeTerminal()), LiveView)


class ClosedPipe(io.StringIO):
    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")


def test_plain_progress_ends_quietly_on_a_closed_pipe():
    # `pmsm-hil run ... | head -n 1`: the events left at the end must not raise out of the run
    live = sample_state()
    with PlainProgress(stream=ClosedPipe(), period_s=1e9) as p:
        p.update(live)  # no line yet: the event waits for the end
