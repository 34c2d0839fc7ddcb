"""Live view of a run (rich), and the plain progress printer used with --no-live or when the
output is not a terminal (a pipe, a file, CI)."""

from __future__ import annotations

import contextlib
import sys
import time
from typing import Any, TextIO

from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.measure import Measurement
from rich.panel import Panel
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from pmsm_hil.recorder import LiveState, fault_text


def _link_use(live: LiveState, bit_rate: float) -> float:
    """Share of the link's capacity used, in device time (10 bits per octet on a UART)."""
    if live.t_s <= 0 or not bit_rate:
        return 0.0
    return live.octets * 10.0 / (bit_rate * live.t_s)


FLAGS_LEGEND = (
    "estimator flags: * feeds the MPCC predictor, e excited (the operating point "
    "lets it learn), c converged, - not (yet); % = error against the plant's truth"
)
FLAGS_LEGEND_SHORT = "flags: * feeds predictor  e excited  c converged  - not yet  %: vs truth"
FLAGS_LEGEND_TINY = "* feeds predictor, e excited,\nc converged, - not yet"


def _flags(name: str, p: dict) -> str:
    """`*` feeds the predictor; e/c: excited / converged (params flags), `-` when not."""
    mark = " *" if p.get("feeds_predictor") else ""
    if name != "nominal":
        mark += " " + ("e" if p.get("excited") else "-") + ("c" if p.get("converged") else "-")
    return name + mark


def _signals(t: dict, estimate: bool = False, title: bool = True) -> Table:
    """estimate: a column with the angle estimator's speed and angle beside the encoder's."""
    sig = Table(
        title="signals" if title else None,
        box=None,
        show_header=True,
        header_style="bold",
        pad_edge=False,
    )
    for col in ("", "ref", "measured") + (("estimate",) if estimate else ()):
        sig.add_column(col, justify="right", no_wrap=True)
    rows = [
        (
            "speed r/min",
            f"{t.get('speed_ref_rpm', 0):8.1f}",
            f"{t.get('speed_rpm', 0):8.1f}",
            f"{t.get('speed_est_rpm', 0):8.1f}",
        ),
        ("i_d A", f"{t.get('i_d_ref_a', 0):8.2f}", f"{t.get('i_d_a', 0):8.2f}", ""),
        ("i_q A", f"{t.get('i_q_ref_a', 0):8.2f}", f"{t.get('i_q_a', 0):8.2f}", ""),
        ("load N·m", f"{t.get('load_nm', 0):8.2f}", "", ""),
        ("θe rad", "", f"{t.get('theta_e_rad', 0):8.3f}", f"{t.get('theta_e_est_rad', 0):8.3f}"),
    ]
    for row in rows:
        sig.add_row(*row[: 4 if estimate else 3])
    return sig


def _parameters(
    live: LiveState, errors: bool = True, fold: bool = False, title: bool = True
) -> Table:
    """errors: the % error against the truth beside each value; fold: wrap cells, never `…`."""
    par = Table(
        title="parameters" if title else None, box=None, header_style="bold", pad_edge=False
    )
    par.add_column("estimator", no_wrap=not fold, overflow="fold")
    for col in ("L_d mH", "L_q mH", "ψf mWb", "R Ω"):
        par.add_column(col, justify="right", no_wrap=not fold, overflow="fold")
    tr = live.truth or {}
    for name, p in live.params.items():

        def cell(key, k, fmt, p=p, name=name):
            v = p[key] * k
            ref = tr.get(key)
            if errors and name != "nominal" and ref:
                return f"{v:{fmt}} [dim]{100 * (p[key] / ref - 1):+.1f}%[/]"
            return f"{v:{fmt}}"

        par.add_row(
            _flags(name, p),
            cell("l_d_h", 1e3, ".3f"),
            cell("l_q_h", 1e3, ".3f"),
            cell("psi_f_wb", 1e3, ".1f"),
            cell("r_s_ohm", 1.0, ".3f"),
        )
    if tr:
        par.add_row(
            "[dim]truth[/]",
            f"[dim]{tr['l_d_h'] * 1e3:.3f}",
            f"[dim]{tr['l_q_h'] * 1e3:.3f}",
            f"[dim]{tr['psi_f_wb'] * 1e3:.1f}",
            f"[dim]{tr['r_s_ohm']:.3f}",
        )
    return par


def _link(live: LiveState, bit_rate: float, wide: bool) -> Table:
    link = Table(title="link", box=None, show_header=False, pad_edge=False)
    link.add_column(justify="right", no_wrap=True)
    link.add_column(no_wrap=True)
    link.add_row(f"{live.frames}", "frames")
    link.add_row(
        f"{_link_use(live, bit_rate) * 100:.1f} %",
        "of capacity (device time)" if wide else "of capacity",
    )
    link.add_row(f"{live.bad_frames}", "bad frames")
    link.add_row(f"{live.seq_gaps}", "sequence gaps")
    link.add_row(
        f"{live.tx_dropped}", "dropped by the device (TX full)" if wide else "dropped (TX full)"
    )
    return link


def _link_line(live: LiveState, bit_rate: float) -> Text:
    """The link's figures on one line (a narrow terminal: the table would take six)."""
    return Text(
        f"link {live.frames} frames, {_link_use(live, bit_rate) * 100:.1f} % used, "
        f"{live.bad_frames} bad, {live.seq_gaps} gaps, {live.tx_dropped} dropped"
    )


def _width(console, options, renderable) -> int:
    return Measurement.get(console, options.update(width=10_000), renderable).maximum


def estimator_text(e: dict, markup: bool = True) -> str:
    """One line on the angle estimator: name, lock, confidence, angle error against the encoder."""
    lock = "locked" if e.get("locked") else "NOT LOCKED"
    if markup:
        lock = f"[{'green' if e.get('locked') else 'red'}]{lock}[/]"
    loop = "closes the loop" if e.get("in_loop") else "not in the loop"
    return (
        f"estimator {e.get('estimator', '?')} {lock} ({loop}), confidence "
        f"{e.get('confidence', 0.0):.2f}, theta_err {e.get('theta_err_rad', 0.0):+.4f} rad, "
        f"speed err {e.get('speed_err_rpm', 0.0):+.1f} r/min"
    )


class _Screen:
    """The live panel, laid out for the console it is drawn on: the three tables side by side
    when they fit, else stacked; as many recent events as the height leaves room for."""

    def __init__(self, live: LiveState, title: str, bit_rate: float, names: list[str]):
        self.live, self.title, self.bit_rate, self.names = live, title, bit_rate, names

    def _body(self, console, options, inner: int) -> list:
        live = self.live
        t = live.telemetry
        seg = self.names[live.segment] if 0 <= live.segment < len(self.names) else ""
        state = (
            f"state [bold]{live.state}[/]  segment {live.segment} {seg}  "
            f"faults [{'red' if live.faults else 'green'}]{fault_text(live.faults)}[/]"
        )
        head = Text.from_markup(f"[bold]{self.title}[/]  {state}")
        rows: list[RenderableType] = (
            [head]
            if head.cell_len <= inner
            else [Text.from_markup(f"[bold]{self.title}[/]"), Text.from_markup(state)]
        )
        counts = f"{live.t_s:7.2f} / {live.total_s:.2f} s  {live.realtime_factor:5.1f}x real time"
        bar_w = max(10, min(50, inner - len(counts) - 2))
        prog = Table.grid(padding=(0, 2))
        prog.add_row(
            ProgressBar(
                total=max(live.total_s, 1e-9), completed=min(live.t_s, live.total_s), width=bar_w
            ),
            counts,
        )
        rows.append(prog)
        estimate = bool(live.estimator)
        sig, par = _signals(t, estimate), _parameters(live)
        wide_link = _link(live, self.bit_rate, True)
        ws, wp, wl = (_width(console, options, x) for x in (sig, par, wide_link))
        gap = next((g for g in (4, 2) if ws + wp + wl + 2 * g <= inner), 0)
        if gap:
            body = Table.grid(padding=(0, gap))
            body.add_row(sig, par, wide_link)
            rows.append(body)
        else:
            link = _link(live, self.bit_rate, False)
            wl = _width(console, options, link)
            titled = ws + wl + 4 <= inner
            if titled:
                top = Table.grid(padding=(0, 4))
                top.add_row(sig, link)
                rows.append(top)
            else:  # stacked: the link on one line, no table titles (the headers say enough)
                rows += [_signals(t, estimate, title=False), _link_line(live, self.bit_rate)]
            par = _parameters(live, title=titled)
            if _width(console, options, par) > inner:
                par = _parameters(live, errors=False, title=titled)
                if _width(console, options, par) > inner:
                    par = _parameters(live, errors=False, fold=True, title=titled)
            rows.append(par)
        if live.estimator:
            rows.append(Text.from_markup(estimator_text(live.estimator)))
        if any(n != "nominal" or p.get("feeds_predictor") for n, p in live.params.items()):
            legend = next(
                (x for x in (FLAGS_LEGEND, FLAGS_LEGEND_SHORT) if len(x) <= inner),
                FLAGS_LEGEND_TINY,
            )
            rows.append(Text(legend, style="dim"))
        return rows

    def __rich_console__(self, console, options):
        width = options.max_width
        inner = width - 4  # panel border and padding
        rows = self._body(console, options, inner)
        height = options.height or console.height
        used = (
            sum(
                len(console.render_lines(r, options.update(width=inner, height=None), pad=False))
                for r in rows
            )
            + 2
        )
        room = max(0, (height or 10_000) - 1 - used)  # one line spare for rich.Live's cursor
        events = (
            [Text(f"{e[0]:8.3f} s  {e[3]}") for e in self.live.events[-min(4, room) :]]
            if room
            else []
        )
        yield Panel(Group(*rows, *events), title="pmsm-hil run", border_style="blue", width=width)


def render(live: LiveState, title: str, bit_rate: float, names: list[str]) -> _Screen:
    """The live panel for `live` (a rich renderable that fits the console's width and height)."""
    return _Screen(live, title, bit_rate, names)


class LiveView:
    """Observer for the runner: a rich Live panel."""

    def __init__(self, title: str, bit_rate: float, names: list[str]):
        self.title, self.bit_rate, self.names = title, bit_rate, names
        # 4 frames a second: live to the eye, and the panel (about 16 ms to lay out and draw)
        # takes 6 % of the host instead of 16 % when the emulator runs far ahead of real time
        self._live = Live(refresh_per_second=4, transient=False)
        self._state: LiveState | None = None

    def __enter__(self) -> LiveView:
        self._live.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._state is not None:
            self._live.update(render(self._state, self.title, self.bit_rate, self.names))
        self._live.__exit__(*exc)

    def update(self, live: LiveState) -> None:
        self._state = live
        self._live.update(render(live, self.title, self.bit_rate, self.names))

    def message(self, text: str) -> None:
        self._live.console.print(text)


class PlainProgress:
    """Observer for --no-live: a line per second of wall time, after the device's events since
    the last line (segments, the polarity test's result, faults ...; the host prints its own)."""

    def __init__(self, stream: TextIO = sys.stdout, period_s: float = 1.0):
        self.stream, self.period_s = stream, period_s
        self._last = 0.0
        self._live: LiveState | None = None
        self._events = 0  # events of self._live printed so far

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        with contextlib.suppress(OSError, ValueError):  # a closed pipe (`| head`) ends nothing
            self._print_events()

    def _print_events(self) -> None:
        events = self._live.events if self._live is not None else []
        for t_s, kind, _arg, text in events[self._events :]:
            if kind not in ("host", "link"):
                print(f"{t_s:8.3f} s  {text}", file=self.stream)
        self._events = len(events)

    def update(self, live: LiveState) -> None:
        self._live = live
        now = time.monotonic()
        if now - self._last < self.period_s:
            return
        self._last = now
        self._print_events()
        t = live.telemetry
        print(
            f"t={live.t_s:7.2f}/{live.total_s:.2f} s  seg {live.segment:2d}  {live.state:8s} "
            f"speed ref/meas {t.get('speed_ref_rpm', 0):7.1f}/{t.get('speed_rpm', 0):7.1f} r/min  "
            f"i_d {t.get('i_d_a', 0):6.2f} A  i_q {t.get('i_q_a', 0):6.2f} A  "
            f"frames {live.frames}  bad {live.bad_frames}  {live.realtime_factor:.1f}x"
            + (f"\n    {estimator_text(live.estimator, markup=False)}" if live.estimator else ""),
            file=self.stream,
            flush=True,
        )

    def message(self, text: str) -> None:
        self._print_events()  # in the order they came
        print(text, file=self.stream, flush=True)


def make_observer(
    no_live: bool, title: str, bit_rate: float, names: list[str], stream: TextIO | None = None
) -> PlainProgress | LiveView:
    """The live view on a terminal; plain lines with --no-live or when the output is piped."""
    stream = sys.stdout if stream is None else stream
    if no_live or not Console(file=stream).is_terminal:
        return PlainProgress(stream=stream)
    return LiveView(title, bit_rate, names)
