"""Turns decoded device frames into log messages (the MCAP contract) and keeps the live state."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from pmsm_hil.protocol import generated as gen

if TYPE_CHECKING:
    from pmsm_hil.log.writer import LogWriter
    from pmsm_hil.protocol.codec import Frame


class Sink(Protocol):
    """An extra consumer of each logged device message (e.g. pmsm_hil.live.foxglove.FoxgloveSink)."""

    def publish(self, topic: str, t_s: float, fields: dict) -> None: ...


STATE_NAMES = {v: k for k, v in gen.ENUMS["state"].items()}
EVENT_NAMES = {v: k for k, v in gen.ENUMS["event"].items()}
ESTIMATOR_NAMES = {v: k for k, v in gen.ENUMS["estimator"].items()}
ANGLE_SRC_NAMES = {v: k for k, v in gen.ENUMS["angle_src"].items()}
EST_FLAGS = gen.ENUMS["est_flag"]
FAULT_BITS = gen.ENUMS["fault"]
STOP_REASONS = {v: k.replace("_", " ") for k, v in gen.ENUMS["stop_reason"].items()}
COMMISSION_STEPS = {v: k for k, v in gen.ENUMS["commission_step"].items()}
COMMISSION_FAILS = {v: k for k, v in gen.ENUMS["commission_fail"].items()}
PARAMS_FLAGS = gen.ENUMS["params_flag"]

TELEMETRY_FIELDS = (
    "speed_ref_rpm",
    "speed_rpm",
    "speed_est_rpm",
    "theta_e_rad",
    "theta_e_est_rad",
    "i_d_a",
    "i_q_a",
    "i_d_ref_a",
    "i_q_ref_a",
    "u_d_v",
    "u_q_v",
    "load_nm",
)
TRUTH_FIELDS = (
    "l_d_h",
    "l_q_h",
    "psi_f_wb",
    "r_s_ohm",
    "theta_e_rad",
    "speed_rpm",
    "torque_nm",
    "temp_winding_c",
    "temp_magnet_c",
    "effects",
    "l_d_secant_h",
    "l_q_secant_h",
)
STATUS_FIELDS = (
    "segment",
    "faults",
    "v_dc_v",
    "tx_dropped",
    "rx_bad",
    "rx_frames",
    "hb_age_ms",
    "capture_count",
)


# device messages written to the log straight from their payload octets when no sink needs their
# fields (Recorder.frames): the busiest ones, whose topic's fields are the message's own
DIRECT = {
    "telem_fast": ("/pmsm/telemetry", TELEMETRY_FIELDS),
    "sim_truth": ("/sim/truth", TRUTH_FIELDS),
}


def direct_encoder(
    msg: str, ts_s: float, names: tuple[str, ...], pack: Callable[..., bytes]
) -> Callable[[bytes], tuple[float, bytes]] | None:
    """Payload octets of device message ``msg`` -> (t_s, the CDR data of its log message), with the
    very operations of the decoder (pmsm_hil.protocol.codec) and the writer: the same values and
    octets. ``names``: the log fields in schema order (``t_s`` first), ``pack`` their CDR pack
    (LogWriter.fixed_layout). None when a log field is not one of the message's."""
    spec = gen.BY_NAME[msg]
    expr: dict[str, str] = {}
    i = 0
    for f in spec.fields:
        if f.count == 1:  # as codec._payload_decoder writes it
            expr[f.name] = f"v[{i}]" + ("" if f.scale is None else f" * {f.scale!r}")
        i += f.count
    if "tick" not in expr or any(n not in expr for n in names[1:]):
        return None
    src = (
        f"def encode_{msg}(p):\n"
        f"    v = unpack(p)\n"
        f"    t = {expr['tick']} * ts_s\n"
        f"    return t, pack(0x100, t, {', '.join(expr[n] for n in names[1:])})\n"
    )
    namespace: dict[str, Any] = {"unpack": spec.struct.unpack, "pack": pack, "ts_s": ts_s}
    exec(compile(src, f"<recorder {msg}>", "exec"), namespace)
    return namespace[f"encode_{msg}"]


def fault_text(bits: int) -> str:
    names = [name for name, b in FAULT_BITS.items() if bits & b]
    return "+".join(names) if names else "none"


@dataclass
class LiveState:
    """What the live view shows; updated from every frame."""

    t_s: float = 0.0
    total_s: float = 0.0
    segment: int = 0
    state: str = "idle"
    faults: int = 0
    telemetry: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)  # estimator -> fields
    estimator: dict = field(default_factory=dict)  # the angle estimator's last frame
    truth: dict = field(default_factory=dict)
    status: dict = field(default_factory=dict)
    frames: int = 0
    octets: int = 0
    seq_gaps: int = 0
    bad_frames: int = 0
    tx_dropped: int = 0
    wall_start: float = field(default_factory=time.monotonic)
    events: list = field(default_factory=list)  # (t_s, kind, arg, text)
    stopped: bool = False
    stop_reason: str = ""
    commission: list = field(default_factory=list)  # /pmsm/commission rows, in order

    @property
    def wall_s(self) -> float:
        return time.monotonic() - self.wall_start

    @property
    def realtime_factor(self) -> float:
        w = self.wall_s
        return self.t_s / w if w > 0 else 0.0


class Recorder:
    """Feeds frames to the log writer (device topics) and to the live state."""

    def __init__(
        self, writer: LogWriter, ts_s: float, segment_names: list[str], sinks: Iterable[Sink] = ()
    ):
        self.w = writer
        self.sinks = list(sinks)  # extra consumers, e.g. pmsm_hil.live.foxglove.FoxgloveSink
        self.ts_s = ts_s
        self.names = segment_names
        self.live = LiveState()
        self._last_seq: int | None = None
        # message id -> (topic, encoder from the payload), made at the message's first frame
        # (its channel opens then, as it would for write); not with sinks, which want the fields
        self._direct: dict[int, tuple[str, Callable[[bytes], tuple[float, bytes]]]] = {}
        self._direct_due = set() if self.sinks else {gen.BY_NAME[m].id for m in DIRECT}

    def _make_direct(
        self, msg_id: int
    ) -> tuple[str, Callable[[bytes], tuple[float, bytes]]] | None:
        self._direct_due.discard(msg_id)
        msg = gen.BY_ID[msg_id].name
        topic, fields = DIRECT[msg]
        layout = self.w.fixed_layout(topic)
        if layout is None or set(layout[0][1:]) != set(fields):
            return None
        enc = direct_encoder(msg, self.ts_s, *layout)
        if enc is None:
            return None
        entry = self._direct[msg_id] = (topic, enc)
        return entry

    def _write(self, topic: str, t_s: float, row: dict) -> None:
        self.w.write(topic, t_s, row)
        for sink in self.sinks:
            sink.publish(topic, t_s, row)

    def _t(self, tick: int) -> float:
        return tick * self.ts_s

    def event(self, t_s: float, kind: str, code: int, arg: int, text: str) -> None:
        self._write("/pmsm/events", t_s, {"kind": kind, "code": code, "arg": arg, "text": text})
        self.live.events.append((t_s, kind, arg, text))

    def frames(self, frames: Iterable[Frame]) -> None:
        """One receive batch: each frame to its handler, then the batch to the OS (the writer's
        journal, pmsm_hil.log.journal), so that a host killed after this call has logged all of it."""
        live = self.live
        direct = self._direct
        items: list[tuple[str, float, bytes]] = []  # direct messages not yet written
        last: dict[int, tuple[float, Frame]] = {}  # the last frame written directly, per message
        n = gaps = 0
        last_seq = self._last_seq
        try:
            for fr in frames:
                n += 1
                seq = fr.seq
                if last_seq is not None and seq != ((last_seq + 1) & 0xFF):
                    gaps += 1
                last_seq = seq
                entry = direct.get(fr.msg_id)
                if entry is None and fr.msg_id in self._direct_due:
                    if items:  # its channel opens after the messages before it
                        self.w.write_data_many(items)
                        items = []
                    entry = self._make_direct(fr.msg_id)
                if entry is not None and fr.payload:
                    t, data = entry[1](fr.payload)
                    items.append((entry[0], t, data))
                    last[fr.msg_id] = (t, fr)
                    continue
                handler = getattr(self, "_on_" + fr.name, None)
                if handler is not None:
                    if items:  # in order
                        self.w.write_data_many(items)
                        items = []
                    handler(fr.fields)
            if items:
                self.w.write_data_many(items)
        finally:
            live.frames += n
            live.seq_gaps += gaps
            self._last_seq = last_seq
            for t, fr in last.values():  # the live state as the handlers would leave it
                if fr.name == "telem_fast":
                    live.t_s = t
                    live.telemetry = {k: fr.fields[k] for k in TELEMETRY_FIELDS}
                else:
                    live.truth = {k: fr.fields[k] for k in TRUTH_FIELDS}
        if n:
            self.w.flush_batch()

    # one handler per device message -------------------------------------------------------
    def _on_telem_fast(self, f: dict) -> None:
        t = self._t(f["tick"])
        row = {k: f[k] for k in TELEMETRY_FIELDS}
        self._write("/pmsm/telemetry", t, row)
        self.live.t_s = t
        self.live.telemetry = row

    def _on_telem_est(self, f: dict) -> None:
        t = self._t(f["tick"])
        flags = f["flags"]
        row = {
            "estimator": ANGLE_SRC_NAMES.get(f["estimator"], str(f["estimator"])),
            "locked": bool(flags & EST_FLAGS["locked"]),
            "in_loop": bool(flags & EST_FLAGS["in_loop"]),
            "confidence": f["confidence"],
            "theta_err_rad": f["theta_err_rad"],
            "speed_err_rpm": f["speed_err_rpm"],
            "err_signal": f["err_signal"],
        }
        self._write("/pmsm/estimator", t, row)
        self.live.estimator = row

    def _on_params(self, f: dict) -> None:
        t = self._t(f["tick"])
        name = ESTIMATOR_NAMES.get(f["estimator"], str(f["estimator"]))
        flags = f["flags"]
        row = {
            "estimator": name,
            "l_d_h": f["l_d_h"],
            "l_q_h": f["l_q_h"],
            "psi_f_wb": f["psi_f_wb"],
            "r_s_ohm": f["r_s_ohm"],
            "excited": bool(flags & PARAMS_FLAGS["excited"]),
            "converged": bool(flags & PARAMS_FLAGS["converged"]),
            "feeds_predictor": bool(flags & PARAMS_FLAGS["feeds_predictor"]),
        }
        self._write("/pmsm/params", t, row)
        self.live.params[name] = row

    def _on_status(self, f: dict) -> None:
        t = self._t(f["tick"])
        state = STATE_NAMES.get(f["state"], str(f["state"]))
        row = {"state": state, **{k: f[k] for k in STATUS_FIELDS}}
        self._write("/pmsm/status", t, row)
        live = self.live
        live.status = row
        live.state = state
        live.faults = f["faults"]
        live.tx_dropped = f["tx_dropped"]
        live.segment = f["segment"]

    def _on_event(self, f: dict) -> None:
        t = self._t(f["tick"])
        code, arg = f["code"], f["arg"]
        kind = EVENT_NAMES.get(code, f"event_{code}")
        if kind == "segment_start":
            name = self.names[arg] if 0 <= arg < len(self.names) else ""
            text = f"segment {arg} {name}".rstrip()
            self.live.segment = arg
        elif kind == "fault":
            text = f"fault: {fault_text(arg)}"
            self.live.faults |= arg
        elif kind == "stopped":
            text = f"stopped: {STOP_REASONS.get(arg, arg)}"
            self.live.stopped = True
            self.live.stop_reason = STOP_REASONS.get(arg, str(arg))
        elif kind == "heartbeat_lost":
            text = f"heartbeat lost: last heartbeat {arg} ms ago"
        elif kind == "commission_step":
            text = f"commissioning: {COMMISSION_STEPS.get(arg, arg)}"
        elif kind == "commission_failed":
            step, why = COMMISSION_STEPS.get(arg >> 8, arg >> 8), arg & 0xFF
            text = f"commissioning failed in {step}: {COMMISSION_FAILS.get(why, why)}"
        elif kind == "capture_triggered":
            text = "capture triggered by " + ("a fault" if arg < 0 else f"segment {arg}")
        else:
            text = kind.replace("_", " ")
        self.event(t, kind, code, arg, text)

    def _on_commission_result(self, f: dict) -> None:
        t = self._t(f["tick"])
        row = {
            "step": COMMISSION_STEPS.get(f["step"], str(f["step"])),
            "status": "ok" if f["status"] == 0 else COMMISSION_FAILS.get(f["status"], "failed"),
        }
        for k in range(len(f["value"])):
            row[f"value_{k}"] = f["value"][k]
            row[f"spread_{k}"] = f["spread"][k]
        row["ref_0"], row["ref_1"] = f["truth_ref"][0], f["truth_ref"][1]
        self._write("/pmsm/commission", t, row)
        self.live.commission.append((t, row))

    def _on_sim_truth(self, f: dict) -> None:
        t = self._t(f["tick"])
        row = {k: f[k] for k in TRUTH_FIELDS}
        self._write("/sim/truth", t, row)
        self.live.truth = row

    def capture(self, chunks: list[dict]) -> int:
        """Writes uploaded capture chunks as /pmsm/capture messages; returns the sample count."""
        n = 0
        for c in chunks:
            for i in range(c["n_valid"]):
                t = self._t(c["tick0"] + c["offset"] + i)
                s = c["s_abc"][i]
                self.w.write(
                    "/pmsm/capture",
                    t,
                    {
                        "i_a_a": c["i_a_a"][i],
                        "i_b_a": c["i_b_a"][i],
                        "i_c_a": c["i_c_a"][i],
                        "s_a": s & 1,
                        "s_b": (s >> 1) & 1,
                        "s_c": (s >> 2) & 1,
                        "v_dc_v": c["v_dc_v"][i],
                        "theta_e_rad": c["theta_e_rad"][i],
                        "omega_e_rad_s": c["omega_e_rad_s"][i],
                    },
                )
                n += 1
        self.w.flush_batch()
        return n
