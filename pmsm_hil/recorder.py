"""Turns decoded device frames into log messages (the MCAP contract) and keeps the live state."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from pmsm_hil.protocol import generated as gen
from pmsm_hil.wire_blocks import block_encoder, wire_dtype

if TYPE_CHECKING:
    from pmsm_hil.log.blocks import MessageBlock
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
# the polarity event's arg: enum polarity_result (docs/sensorless.md, "Polarity")
_POLARITY_TEXT = {
    "kept": "kept (the estimate was on the magnet's axis)",
    "flipped": "flipped (the estimate was half a turn off and has been turned)",
    "unresolved": "not resolved (the d-axis asymmetry is too small: the motor stops)",
    "no_lock": "no lock at rest (the PLL did not lock before the pulses: the motor stops)",
}
POLARITY_RESULTS = {
    v: _POLARITY_TEXT.get(k, k.replace("_", " ")) for k, v in gen.ENUMS["polarity_result"].items()
}

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
# and the estimators' parameters, one layout per estimator (its name is a string in the log): a
# params frame's key in a batch is PARAMS_KEY | the estimator's code (Recorder.frames)
PARAMS_ID = gen.BY_NAME["params"].id
PARAMS_KEY = 0x10000
_ESTIMATOR_AT = wire_dtype("params").fields["estimator"][1]  # type: ignore[index]
PARAMS_BITS = {n: ("flags", PARAMS_FLAGS[n]) for n in ("excited", "converged", "feeds_predictor")}


def fault_text(bits: int) -> str:
    names = [name for name, b in FAULT_BITS.items() if bits & b]
    return "+".join(names) if names else "none"


# The motor file's limit that each protection fault trips on (sent in config_motor).
FAULT_LIMITS = {
    "over_current": ("i_trip_a", "A"),
    "over_speed": ("speed_trip_rpm", "r/min"),
    "dc_under_voltage": ("v_dc_min_v", "V"),
    "dc_over_voltage": ("v_dc_max_v", "V"),
}


def fault_limits_text(bits: int, motor: object) -> str:
    """``fault_text`` with the motor file's limit behind each protection fault, e.g.
    "over_speed: beyond speed_trip_rpm 3000 r/min of motors/m.yaml"."""
    path = getattr(motor, "path", "") or "the motor file"
    parts = []
    for name, b in FAULT_BITS.items():
        if bits & b:
            key, unit = FAULT_LIMITS.get(name, ("", ""))
            value = getattr(motor, key, None) if key else None
            limit = f": beyond {key} {value:g} {unit} of {path}" if value is not None else ""
            parts.append(name + limit)
    return "; ".join(parts) if parts else "none"


def _estimator_name(code: int) -> str:
    return ESTIMATOR_NAMES.get(code, str(code))


def _params_row(f: dict) -> tuple[str, dict]:
    """A params frame's estimator and its /pmsm/params fields."""
    name = _estimator_name(f["estimator"])
    flags = f["flags"]
    row = {
        "estimator": name,
        "l_d_h": f["l_d_h"],
        "l_q_h": f["l_q_h"],
        "psi_f_wb": f["psi_f_wb"],
        "r_s_ohm": f["r_s_ohm"],
        **{k: bool(flags & mask) for k, (_, mask) in PARAMS_BITS.items()},
    }
    return name, row


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
        self._direct: dict[int, tuple[str, Callable[[bytes], tuple[np.ndarray, np.ndarray]]]] = {}
        self._direct_ids = (
            set() if self.sinks else {gen.BY_NAME[m].id for m in DIRECT} | {PARAMS_ID}
        )
        self._not_direct: set[int] = set()  # keys found to need their handler

    def _make_direct(
        self, key: int
    ) -> tuple[str, Callable[[bytes], tuple[np.ndarray, np.ndarray]]] | None:
        enc = None
        if key & PARAMS_KEY:
            topic = "/pmsm/params"
            name = _estimator_name(key & 0xFF)
            layout = self.w.fixed_layout(topic, {"estimator": name})
            if layout is not None:
                enc = block_encoder(
                    "params", self.ts_s, layout.names, layout.dtype, layout.template, PARAMS_BITS
                )
        elif key in self._direct_ids:
            msg = gen.BY_ID[key].name
            topic, fields = DIRECT[msg]
            layout = self.w.fixed_layout(topic)
            if layout is not None and set(layout.names[1:]) == set(fields):
                enc = block_encoder(msg, self.ts_s, layout.names, layout.dtype)
        if enc is None:
            self._not_direct.add(key)
            return None
        entry = self._direct[key] = (topic, enc)
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
        journal, pmsm_hil.log.journal), so that a host killed after this call has logged all of it.

        The DIRECT messages go to the log without their handlers: each one's frames in the batch
        encoded at once (``block_encoder``), then written run by run, in the order received,
        between the other frames' messages (LogWriter.write_runs: the runs up to the next frame
        that needs its handler, at once)."""
        frames = frames if isinstance(frames, list) else list(frames)
        live = self.live
        n = len(frames)
        # a frame's key: its id (params: PARAMS_KEY | the estimator's code), or -1 - id without
        # payload octets (its fields only: a handler)
        pid, at = (PARAMS_ID if self._direct_ids else -1), _ESTIMATOR_AT
        keys = [
            (fr.msg_id if fr.msg_id != pid else PARAMS_KEY | fr.payload[at])
            if fr.payload
            else -1 - fr.msg_id
            for fr in frames
        ]
        blocks: dict[int, MessageBlock] = {}  # id -> its frames in this batch, as log records
        last: dict[int, Frame] = {}  # the last frame written directly, per message
        # runs of directly written frames, written at once before the next handler's frame and
        # at the batch's end: (block, stop), and the last frame of each block queued so far
        runs: list[tuple[MessageBlock, int]] = []
        queued: dict[int, int] = {}
        queued_last: dict[int, Frame] = {}
        i = done = 0  # frames looked at / written

        def write_queued() -> None:
            self.w.write_runs(runs)
            runs.clear()
            last.update(queued_last)
            queued_last.clear()

        try:
            while i < n:
                key = keys[i]
                j = i + 1
                while j < n and keys[j] == key:
                    j += 1
                entry = self._direct.get(key)
                if entry is None and key >= 0 and self._direct_ids and key not in self._not_direct:
                    if runs:  # it may open a channel: after the runs before it
                        write_queued()
                    entry = self._make_direct(key)
                if entry is None:
                    if runs:
                        write_queued()
                    done = i
                    for fr in frames[i:j]:
                        handler = getattr(self, "_on_" + fr.name, None)
                        if handler is not None:
                            handler(fr.fields)
                else:
                    block = blocks.get(key)
                    if block is None:
                        if runs:  # its channel may open now: after the runs before it
                            write_queued()
                        payloads = b"".join(
                            [f.payload for f, k in zip(frames, keys, strict=True) if k == key]
                        )
                        t, data = entry[1](payloads)
                        block = blocks[key] = self.w.message_block(entry[0], t, data)
                    stop = queued[key] = queued.get(key, 0) + (j - i)
                    runs.append((block, stop))
                    queued_last[key] = frames[j - 1]
                i = j
                if not runs:
                    done = i
            if runs:
                write_queued()
            done = i
        finally:
            live.frames += done
            self._count_gaps(frames[:done])
            for fr in last.values():  # the live state as the handlers would leave it
                if fr.name == "telem_fast":
                    live.t_s = self._t(fr.fields["tick"])
                    live.telemetry = {k: fr.fields[k] for k in TELEMETRY_FIELDS}
                elif fr.name == "params":
                    name, row = _params_row(fr.fields)
                    live.params[name] = row
                else:
                    live.truth = {k: fr.fields[k] for k in TRUTH_FIELDS}
        if n:
            self.w.flush_batch()

    def _count_gaps(self, frames: list[Frame]) -> None:
        """Sequence numbers that do not follow the one before (the batch's and the last batch's)."""
        last_seq, gaps = self._last_seq, 0
        for fr in frames:
            seq = fr.seq
            if last_seq is not None and seq != ((last_seq + 1) & 0xFF):
                gaps += 1
            last_seq = seq
        self._last_seq = last_seq
        self.live.seq_gaps += gaps

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
        name, row = _params_row(f)
        self._write("/pmsm/params", self._t(f["tick"]), row)
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
        elif kind == "r_identified":
            text = f"R identified: {arg / 1000:.3f} ohm"
        elif kind == "polarity":
            text = f"polarity: {POLARITY_RESULTS.get(arg, f'result {arg}')}"
        elif kind == "polarity_asym":
            text = f"polarity test: d-axis asymmetry {arg / 10000:+.4f}"
        elif kind == "if_handover":
            text = f"I/f start: the estimator takes the angle over at {arg / 10:.1f} r/min"
        elif kind == "if_failed":
            text = "I/f start failed: the rotor does not follow (pulled out or stalled)"
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
