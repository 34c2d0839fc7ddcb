"""Live view of a run (rich), and the plain progress printer used with --no-live."""
from __future__ import annotations

import sys
import time

from rich.console import Group
from rich.live import Live
from rich.panel import Panel
from rich.progress_bar import ProgressBar
from rich.table import Table

from pmsm_hil.recorder import LiveState, fault_text


def _link_use(live: LiveState, bit_rate: float) -> float:
    """Share of the link's capacity used, in device time (10 bits per octet on a UART)."""
    if live.t_s <= 0 or not bit_rate:
        return 0.0
    return live.octets * 10.0 / (bit_rate * live.t_s)


def render(live: LiveState, title: str, bit_rate: float, names: list[str]):
    t = live.telemetry
    seg = names[live.segment] if 0 <= live.segment < len(names) else ""
    head = Table.grid(padding=(0, 2))
    head.add_row(f"[bold]{title}[/]", f"state [bold]{live.state}[/]",
                 f"segment {live.segment} {seg}",
                 f"faults [{'red' if live.faults else 'green'}]{fault_text(live.faults)}[/]")
    prog = ProgressBar(total=max(live.total_s, 1e-9), completed=min(live.t_s, live.total_s), width=50)
    prog_row = Table.grid(padding=(0, 2))
    prog_row.add_row(prog, f"{live.t_s:7.2f} / {live.total_s:.2f} s",
                     f"{live.realtime_factor:5.1f}x real time")

    sig = Table(title="signals", box=None, show_header=True, header_style="bold")
    for col in ("", "ref", "measured"):
        sig.add_column(col, justify="right")
    sig.add_row("speed r/min", f"{t.get('speed_ref_rpm', 0):8.1f}", f"{t.get('speed_rpm', 0):8.1f}")
    sig.add_row("i_d A", f"{t.get('i_d_ref_a', 0):8.2f}", f"{t.get('i_d_a', 0):8.2f}")
    sig.add_row("i_q A", f"{t.get('i_q_ref_a', 0):8.2f}", f"{t.get('i_q_a', 0):8.2f}")
    sig.add_row("load N·m", f"{t.get('load_nm', 0):8.2f}", "")
    sig.add_row("θe rad", "", f"{t.get('theta_e_rad', 0):8.3f}")

    par = Table(title="parameters", box=None, header_style="bold")
    par.add_column("estimator")
    for col in ("L_d mH", "L_q mH", "ψf mWb", "R Ω"):
        par.add_column(col, justify="right")
    for name, p in live.params.items():
        # markers: * feeds the predictor, e excited, c converged (params flags)
        mark = (" *" if p.get("feeds_predictor") else "") + \
               ("" if name == "nominal" else " " + ("e" if p.get("excited") else "-") +
                ("c" if p.get("converged") else "-"))
        tr = live.truth or {}

        def cell(key, k, fmt):
            v = p[key] * k
            ref = tr.get(key)
            if name != "nominal" and ref:
                return f"{v:{fmt}} [dim]{100 * (p[key] / ref - 1):+.1f}%[/]"
            return f"{v:{fmt}}"
        par.add_row(name + mark, cell("l_d_h", 1e3, ".3f"), cell("l_q_h", 1e3, ".3f"),
                    cell("psi_f_wb", 1e3, ".1f"), cell("r_s_ohm", 1.0, ".3f"))
    if live.truth:
        tr = live.truth
        par.add_row("[dim]truth[/]", f"[dim]{tr['l_d_h'] * 1e3:.3f}", f"[dim]{tr['l_q_h'] * 1e3:.3f}",
                    f"[dim]{tr['psi_f_wb'] * 1e3:.1f}", f"[dim]{tr['r_s_ohm']:.3f}")

    link = Table(title="link", box=None, show_header=False)
    link.add_column(justify="right")
    link.add_column()
    link.add_row(f"{live.frames}", "frames")
    link.add_row(f"{_link_use(live, bit_rate) * 100:.1f} %", "of capacity (device time)")
    link.add_row(f"{live.bad_frames}", "bad frames")
    link.add_row(f"{live.seq_gaps}", "sequence gaps")
    link.add_row(f"{live.tx_dropped}", "dropped by the device (TX full)")

    body = Table.grid(padding=(0, 4))
    body.add_row(sig, par, link)
    last = [f"{e[0]:8.3f} s  {e[3]}" for e in live.events[-4:]]
    return Panel(Group(head, prog_row, body, *last), title="pmsm-hil run", border_style="blue")


class LiveView:
    """Observer for the runner: a rich Live panel."""

    def __init__(self, title: str, bit_rate: float, names: list[str]):
        self.title, self.bit_rate, self.names = title, bit_rate, names
        self._live = Live(refresh_per_second=10, transient=False)
        self._state = None

    def __enter__(self):
        self._live.__enter__()
        return self

    def __exit__(self, *exc):
        if self._state is not None:
            self._live.update(render(self._state, self.title, self.bit_rate, self.names))
        self._live.__exit__(*exc)

    def update(self, live: LiveState) -> None:
        self._state = live
        self._live.update(render(live, self.title, self.bit_rate, self.names))

    def message(self, text: str) -> None:
        self._live.console.print(text)


class PlainProgress:
    """Observer for --no-live: a line per second of wall time."""

    def __init__(self, stream=sys.stdout, period_s: float = 1.0):
        self.stream, self.period_s = stream, period_s
        self._last = 0.0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass

    def update(self, live: LiveState) -> None:
        now = time.monotonic()
        if now - self._last < self.period_s:
            return
        self._last = now
        t = live.telemetry
        print(f"t={live.t_s:7.2f}/{live.total_s:.2f} s  seg {live.segment:2d}  {live.state:8s} "
              f"speed {t.get('speed_ref_rpm', 0):7.1f}/{t.get('speed_rpm', 0):7.1f} r/min  "
              f"i_d {t.get('i_d_a', 0):6.2f} A  i_q {t.get('i_q_a', 0):6.2f} A  "
              f"frames {live.frames}  bad {live.bad_frames}  {live.realtime_factor:.1f}x",
              file=self.stream, flush=True)

    def message(self, text: str) -> None:
        print(text, file=self.stream, flush=True)
