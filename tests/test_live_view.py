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
    assert (
        lines[0].startswith("t=  12.50/32.50 s")
        and "speed ref/meas   240.0/  239.7 r/min" in lines[0]
    )
    assert lines[1] == "uploading capture"


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
    assert out.getvalue().startswith("t=  12.50/32.50 s")
    assert isinstance(make_observer(True, "x", 1.0, [], stream=out), PlainProgress)
    assert isinstance(make_observer(False, "x", 1.0, [], stream=FakeTerminal()), LiveView)
