"""The live view shows what an engineer tuning a drive looks at, and --no-live prints plain lines."""
from __future__ import annotations

import io

from rich.console import Console

from pmsm_hil.cli.live import PlainProgress, render
from pmsm_hil.recorder import LiveState


def sample_state() -> LiveState:
    live = LiveState(t_s=12.5, total_s=32.5, segment=4, state="running", frames=25000,
                     octets=1_000_000, bad_frames=3, seq_gaps=2, tx_dropped=0)
    live.telemetry = {"speed_ref_rpm": 240.0, "speed_rpm": 239.7, "i_d_a": -0.81, "i_q_a": 4.52,
                      "i_d_ref_a": -0.76, "i_q_ref_a": 4.50, "load_nm": 5.0, "theta_e_rad": 1.234}
    live.params["nominal"] = {"l_d_h": 0.005, "l_q_h": 0.012, "psi_f_wb": 0.18, "r_s_ohm": 0.9,
                              "feeds_predictor": True}
    live.truth = {"l_d_h": 0.005, "l_q_h": 0.012, "psi_f_wb": 0.18, "r_s_ohm": 0.9}
    live.events.append((12.0, "segment_start", 4, "segment 4 240 r/min load on"))
    return live


def test_live_panel_shows_progress_signals_parameters_and_link():
    con = Console(file=io.StringIO(), width=160, color_system=None)
    con.print(render(sample_state(), "paper-a on emulator", 921600.0, [f"s{i}" for i in range(13)]))
    text = con.file.getvalue()
    assert "12.50 / 32.50 s" in text
    assert "running" in text and "segment 4 s4" in text
    assert "240.0" in text and "239.7" in text          # speed ref / measured
    assert "4.50" in text and "4.52" in text            # i_q ref / measured
    assert "12.000" in text                              # L_q in mH
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
    assert lines[0].startswith("t=  12.50/32.50 s") and "speed   240.0/  239.7 r/min" in lines[0]
    assert lines[1] == "uploading capture"
