"""The log contract: MCAP topics, their ros2msg schemas, and a CDR codec compiled per schema.

Every message is ros2msg + CDR (little endian, classic CDR alignment: each primitive aligned to its
own size, counted from the byte after the 4-octet encapsulation header; strings are a uint32 length
that includes the terminating NUL, the bytes, then the NUL). Foxglove and ``mcap_ros2`` decode the
logs without project code; this module encodes and decodes them fast because it knows the layouts.

docs/log-format.md documents every topic and field.
"""

from __future__ import annotations

import hashlib
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "DEVICE_TOPICS",
    "ESTIMATORS",
    "EVENT_KINDS",
    "HOST_TOPICS",
    "LOG_FORMAT_VERSION",
    "MESSAGE_ENCODING",
    "PRIMITIVES",
    "SCHEMA_ENCODING",
    "TOPICS",
    "Codec",
    "FieldDef",
    "TopicDef",
    "codec_for",
    "schema_hash",
]

LOG_FORMAT_VERSION = 1
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
CDR_LE_HEADER = b"\x00\x01\x00\x00"  # encapsulation kind CDR_LE, options 0

EVENT_KINDS = (
    "segment_start",
    "fault",
    "profile_done",
    "heartbeat_lost",
    "warning",
    "capture_triggered",
    "stopped",
    "started",
    "commission_step",
    "commission_failed",
    "link",
    "host",
)
ESTIMATORS = ("nominal", "rls", "adaline", "nlms_adaline")

# ros2msg type -> (struct code, size = alignment, numpy dtype, default value for a missing field)
PRIMITIVES: dict[str, tuple[str, int, str, Any]] = {
    "bool": ("?", 1, "?", False),
    "int8": ("b", 1, "i1", 0),
    "uint8": ("B", 1, "u1", 0),
    "int16": ("h", 2, "<i2", 0),
    "uint16": ("H", 2, "<u2", 0),
    "int32": ("i", 4, "<i4", 0),
    "uint32": ("I", 4, "<u4", 0),
    "int64": ("q", 8, "<i8", 0),
    "uint64": ("Q", 8, "<u8", 0),
    "float32": ("f", 4, "<f4", float("nan")),
    "float64": ("d", 8, "<f8", float("nan")),
}


@dataclass(frozen=True)
class FieldDef:
    name: str
    type: str  # a ros2msg primitive type or "string"
    unit: str = ""
    doc: str = ""

    @property
    def default(self) -> Any:
        return "" if self.type == "string" else PRIMITIVES[self.type][3]


@dataclass(frozen=True)
class TopicDef:
    topic: str
    schema_name: str
    fields: tuple[FieldDef, ...]
    rate: str = ""
    doc: str = ""
    deterministic: bool = True  # same profile, rig and seed -> same values

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fields)

    @property
    def msgdef(self) -> str:
        """The ros2msg schema text (units and meaning as comments)."""
        lines = [f"# {self.topic}: {self.doc}"] if self.doc else []
        for f in self.fields:
            note = "; ".join(x for x in (f"[{f.unit}]" if f.unit else "", f.doc) if x)
            lines.append(f"{f.type} {f.name}" + (f"  # {note}" if note else ""))
        return "\n".join(lines) + "\n"


def _f(name: str, unit: str = "", doc: str = "", type: str = "float64") -> FieldDef:
    return FieldDef(name, type, unit, doc)


T = _f("t_s", "s", "device time: control periods since start x ts_s")

TOPICS: dict[str, TopicDef] = {
    t.topic: t
    for t in (
        TopicDef(
            "/pmsm/telemetry",
            "pmsm_hil/msg/Telemetry",
            (
                T,
                _f("speed_ref_rpm", "r/min", "speed reference (after the profile's ramp)"),
                _f("speed_rpm", "r/min", "encoder speed (truth when an encoder is fitted)"),
                _f(
                    "speed_est_rpm",
                    "r/min",
                    "speed the firmware uses (encoder until a sensorless estimator runs)",
                ),
                _f("theta_e_rad", "rad", "electrical angle from the encoder, 0..2pi"),
                _f("theta_e_est_rad", "rad", "electrical angle the firmware uses, 0..2pi"),
                _f("i_d_a", "A", "measured d-axis current"),
                _f("i_q_a", "A", "measured q-axis current"),
                _f("i_d_ref_a", "A", "d-axis current reference"),
                _f("i_q_ref_a", "A", "q-axis current reference"),
                _f(
                    "u_d_v", "V", "applied d-axis voltage (as commanded), mean since the last frame"
                ),
                _f(
                    "u_q_v", "V", "applied q-axis voltage (as commanded), mean since the last frame"
                ),
                _f("load_nm", "N m", "load torque commanded by the profile"),
            ),
            "telemetry.fast_hz (<= 2 kHz)",
            "fast telemetry frame",
        ),
        TopicDef(
            "/pmsm/estimator",
            "pmsm_hil/msg/Estimator",
            (
                T,
                _f(
                    "estimator",
                    "",
                    "the angle slot's occupant: mras, ripple_pll or hybrid",
                    "string",
                ),
                _f("locked", "", "the estimator tracks the rotor", "bool"),
                _f(
                    "in_loop",
                    "",
                    "its angle closes the loop (not an angle_encoder segment)",
                    "bool",
                ),
                _f("confidence", "", "0..1, 1 = its residual fully explained"),
                _f("theta_err_rad", "rad", "estimated minus encoder electrical angle, wrapped"),
                _f("speed_err_rpm", "r/min", "estimated minus encoder speed"),
                _f("err_signal", "rad", "the estimator's normalised error signal"),
            ),
            "telemetry.est_hz (only when control.angle_src is an estimator)",
            "the angle estimator's state against the encoder",
        ),
        TopicDef(
            "/pmsm/params",
            "pmsm_hil/msg/Params",
            (
                T,
                _f("estimator", "", "nominal, rls, adaline or nlms_adaline", "string"),
                _f("l_d_h", "H", "estimated d-axis inductance"),
                _f("l_q_h", "H", "estimated q-axis inductance"),
                _f("psi_f_wb", "Wb", "estimated permanent-magnet flux linkage"),
                _f("r_s_ohm", "ohm", "estimated stator resistance"),
                _f("excited", "", "the operating point excites the estimator", "bool"),
                _f("converged", "", "the estimate has settled", "bool"),
                _f(
                    "feeds_predictor", "", "this estimator's values feed the MPCC predictor", "bool"
                ),
            ),
            "telemetry.params_hz (~100 Hz) per estimator",
            "identified motor parameters",
        ),
        TopicDef(
            "/pmsm/capture",
            "pmsm_hil/msg/Capture",
            (
                T,
                _f("i_a_a", "A", "phase a current sample"),
                _f("i_b_a", "A", "phase b current sample"),
                _f("i_c_a", "A", "phase c current sample"),
                _f(
                    "s_a",
                    "",
                    "switch state of leg a applied over the period (1 = upper on)",
                    "uint8",
                ),
                _f("s_b", "", "switch state of leg b", "uint8"),
                _f("s_c", "", "switch state of leg c", "uint8"),
                _f("v_dc_v", "V", "DC-link voltage"),
                _f("theta_e_rad", "rad", "electrical angle (encoder)"),
                _f("omega_e_rad_s", "rad/s", "electrical angular speed"),
            ),
            "1/ts_s in bursts (uploaded after the run)",
            "control-rate capture",
        ),
        TopicDef(
            "/pmsm/status",
            "pmsm_hil/msg/Status",
            (
                T,
                _f("state", "", "idle, running, stopping, fault or done", "string"),
                _f("segment", "", "index of the running profile segment", "int32"),
                _f(
                    "faults",
                    "",
                    "fault bits: 1 over_current, 2 over_speed, 4 dc_under_voltage, "
                    "8 dc_over_voltage, 16 heartbeat, 32 lost_lock",
                    "uint16",
                ),
                _f("v_dc_v", "V", "measured DC-link voltage"),
                _f(
                    "tx_dropped",
                    "",
                    "frames the device dropped because its TX buffer was full",
                    "uint32",
                ),
                _f("rx_bad", "", "frames the device rejected (CRC, COBS, length)", "uint32"),
                _f("rx_frames", "", "frames the device received", "uint32"),
                _f("hb_age_ms", "ms", "age of the last heartbeat", "uint16"),
                _f("capture_count", "", "samples held in the capture buffer", "uint16"),
            ),
            "telemetry.status_hz (10 Hz)",
            "device state and link counters",
            deterministic=False,
        ),
        TopicDef(
            "/pmsm/events",
            "pmsm_hil/msg/Event",
            (
                T,
                _f("kind", "", ", ".join(EVENT_KINDS[:-1]) + " or " + EVENT_KINDS[-1], "string"),
                _f(
                    "code",
                    "",
                    "device event code (firmware/proto/pmsm_proto.yaml enum event), 0 for host events",
                    "int32",
                ),
                _f(
                    "arg",
                    "",
                    "segment index, fault bits, heartbeat age in ms, warning code, ...",
                    "int32",
                ),
                _f("text", "", "human-readable description", "string"),
            ),
            "on change",
            "segment changes, faults, warnings, link and host events",
        ),
        TopicDef(
            "/pmsm/commission",
            "pmsm_hil/msg/CommissionResult",
            (
                T,
                _f("step", "", "offsets, v_dc, encoder, inverter, r_s, l_dq or psi_f", "string"),
                _f("status", "", "ok or the reason it failed (enum commission_fail)", "string"),
                _f("value_0", "", "the step's first result (docs/commissioning.md)"),
                _f("value_1", "", "second result"),
                _f("value_2", "", "third result"),
                _f("value_3", "", "fourth result"),
                _f("value_4", "", "fifth result"),
                _f("value_5", "", "sixth result"),
                _f("spread_0", "", "spread of value_0 over the step's repetitions"),
                _f("spread_1", "", "spread of value_1"),
                _f("spread_2", "", "spread of value_2"),
                _f("spread_3", "", "spread of value_3"),
                _f("spread_4", "", "spread of value_4"),
                _f("spread_5", "", "spread of value_5"),
                _f("ref_0", "", "step-specific operating point or extra result"),
                _f("ref_1", "", "step-specific operating point or extra result"),
            ),
            "once per commissioning step",
            "the firmware's commissioning results (`pmsm-hil commission`)",
        ),
        TopicDef(
            "/sim/truth",
            "pmsm_hil/msg/SimTruth",
            (
                T,
                _f("l_d_h", "H", "true d-axis inductance of the plant (incremental, dpsi_d/di_d)"),
                _f("l_q_h", "H", "true q-axis inductance (incremental, dpsi_q/di_q)"),
                _f("psi_f_wb", "Wb", "true flux linkage"),
                _f("r_s_ohm", "ohm", "true stator resistance"),
                _f("theta_e_rad", "rad", "true electrical angle"),
                _f("speed_rpm", "r/min", "true mechanical speed"),
                _f("torque_nm", "N m", "electromagnetic torque"),
                _f("temp_winding_c", "degC", "winding temperature"),
                _f("temp_magnet_c", "degC", "magnet temperature"),
                _f(
                    "effects",
                    "",
                    "bit mask of the rig effects that are on (pmsm_hil.profiles.EFFECT_BITS)",
                    "uint32",
                ),
                _f(
                    "l_d_secant_h",
                    "H",
                    "apparent d-axis inductance at the operating point, what steady-state "
                    "equations identify: on a flux map the slope of the least-squares line "
                    "through 1 ms means of (i_d, psi_d) over about 0.1 s when i_d is excited, "
                    "else (psi_d - psi_d(0, i_q)) / i_d",
                ),
                _f("l_q_secant_h", "H", "apparent (secant) q-axis inductance, psi_q / i_q"),
            ),
            "telemetry.truth_hz (emulator only)",
            "the emulated plant's true state",
        ),
        TopicDef(
            "/host/link",
            "pmsm_hil/msg/HostLink",
            (
                T,
                _f("wall_s", "s", "host wall-clock seconds since the run started"),
                _f("frames_ok", "", "frames decoded", "uint32"),
                _f("crc_errors", "", "frames with a bad CRC", "uint32"),
                _f("cobs_errors", "", "frames with bad COBS", "uint32"),
                _f("len_errors", "", "frames of the wrong length", "uint32"),
                _f("unknown_id", "", "frames with an unknown id", "uint32"),
                _f("octets", "", "octets received", "uint32"),
                _f("seq_gaps", "", "gaps in the frame sequence numbers", "uint32"),
            ),
            "host side, about 1 Hz and at the end",
            "host-side link statistics (wall-clock based)",
            deterministic=False,
        ),
    )
}

DEVICE_TOPICS = tuple(t for t in TOPICS if not t.startswith("/host/"))
HOST_TOPICS = tuple(t for t in TOPICS if t.startswith("/host/"))


def schema_hash(topics: Iterable[TopicDef] | None = None) -> str:
    """sha256 (hex, first 16 digits) over every schema name and text: changes when the contract does."""
    h = hashlib.sha256()
    for t in sorted(topics if topics is not None else TOPICS.values(), key=lambda t: t.topic):
        h.update(f"{t.topic}\n{t.schema_name}\n{t.msgdef}\n".encode())
    return h.hexdigest()[:16]


# ----------------------------------------------------------------------------------- CDR codec


def _run_struct(fields: Sequence[FieldDef], start_mod8: int) -> tuple[struct.Struct, int]:
    """Struct for a run of primitive fields starting at CDR offset = start_mod8 (mod 8)."""
    fmt = "<"
    off = start_mod8
    for f in fields:
        code, size, _, _ = PRIMITIVES[f.type]
        pad = (-off) % size
        fmt += "x" * pad + code
        off += pad + size
    return struct.Struct(fmt), off - start_mod8


class Codec:
    """Encoder/decoder of one topic's CDR messages (with the 4-octet encapsulation header)."""

    def __init__(self, topic: TopicDef):
        self.topic = topic
        self.fields = topic.fields
        self.names = topic.names
        if not self.fields or self.fields[0].name != "t_s" or self.fields[0].type != "float64":
            raise ValueError(f"{topic.topic}: the first field must be float64 t_s")
        for f in self.fields:
            if f.type != "string" and f.type not in PRIMITIVES:
                raise ValueError(f"{topic.topic}.{f.name}: unsupported type {f.type}")
        self.fixed = all(f.type != "string" for f in self.fields)
        self._layouts: dict[tuple[tuple[str, str], ...], tuple[np.dtype, bytes]] = {}
        self.defaults = tuple(f.default for f in self.fields)
        # plan: list of ("run", fields, [struct per start mod 8]) | ("str", field)
        self.plan: list[tuple] = []
        run: list[FieldDef] = []
        for f in self.fields:
            if f.type == "string":
                if run:
                    self.plan.append(("run", len(run), [_run_struct(run, m) for m in range(8)]))
                    run = []
                self.plan.append(("str", 1, None))
            else:
                run.append(f)
        if run:
            self.plan.append(("run", len(run), [_run_struct(run, m) for m in range(8)]))
        self.body_format: str | None
        self.size: int | None
        self.data_struct: struct.Struct | None
        self.dtype: np.dtype | None
        if self.fixed:
            body, size = _run_struct(self.fields, 0)
            self.body_format = body.format[1:]  # without "<"
            self.size = 4 + size  # data size incl. the encapsulation header
            self.data_struct = struct.Struct("<4s" + self.body_format)
            self.dtype = self.layout()[0]  # header + fields at their CDR offsets
        else:
            self.body_format = None
            self.size = None
            self.data_struct = None
            self.dtype = None

    def layout(self, strings: Mapping[str, str] | None = None) -> tuple[np.dtype, bytes]:
        """The numpy layout of the whole CDR data (header included; the non-string fields at their
        offsets as ``encode`` pads them) and its template: the encapsulation header and the
        strings in place, zeros elsewhere. A topic with strings needs each one's value
        (``strings``: field -> text; ValueError names one not given)."""
        key = tuple(sorted((strings or {}).items()))
        got = self._layouts.get(key)
        if got is not None:
            return got
        given = dict(key)
        names, formats, offsets = [], [], []
        tpl = bytearray(CDR_LE_HEADER)
        off = 0  # CDR offset, after the header
        for f in self.fields:
            if f.type == "string":
                if f.name not in given:
                    raise ValueError(
                        f"{self.topic.topic}.{f.name}: a string field without its value"
                    )
                b = given[f.name].encode("utf-8")
                pad = (-off) & 3
                tpl += b"\0" * pad + struct.pack("<I", len(b) + 1) + b + b"\0"
                off += pad + 4 + len(b) + 1
                continue
            _, size, dt, _ = PRIMITIVES[f.type]
            off += (-off) % size
            names.append(f.name)
            formats.append(dt)
            offsets.append(4 + off)
            off += size
            tpl += b"\0" * (4 + off - len(tpl))
        spec = {"names": names, "formats": formats, "offsets": offsets, "itemsize": len(tpl)}
        got = self._layouts[key] = (np.dtype(spec), bytes(tpl))  # type: ignore[call-overload]
        return got

    # ------------------------------------------------------------------ encode
    def encode(self, values: Sequence[Any]) -> bytes:
        """CDR data (header included) for ``values`` in field order (t_s first)."""
        if self.fixed:
            assert self.data_struct is not None  # set for every fixed-size schema
            return self.data_struct.pack(CDR_LE_HEADER, *values)
        parts = [CDR_LE_HEADER]
        off = 0
        i = 0
        for kind, n, structs in self.plan:
            if kind == "run":
                st, size = structs[off & 7]
                parts.append(st.pack(*values[i : i + n]))
                off += size
            else:
                v = values[i]
                if not isinstance(v, str):
                    raise TypeError(
                        f"{self.topic.topic}.{self.names[i]}: expected text, got {type(v).__name__}"
                    )
                b = v.encode("utf-8")
                pad = (-off) & 3
                parts.append(b"\0" * pad + struct.pack("<I", len(b) + 1) + b + b"\0")
                off += pad + 4 + len(b) + 1
            i += n
        return b"".join(parts)

    # ------------------------------------------------------------------ decode
    def decode(self, data: bytes | memoryview) -> tuple:
        """Values in field order from one message's CDR data."""
        if data[:2] != b"\x00\x01":
            raise ValueError(
                f"{self.topic.topic}: not little-endian CDR (header {bytes(data[:4])!r})"
            )
        if self.fixed:
            assert self.data_struct is not None
            return self.data_struct.unpack_from(data, 0)[1:]
        out: list[Any] = []
        off = 0  # CDR offset (data offset - 4)
        for kind, _n, structs in self.plan:
            if kind == "run":
                st, size = structs[off & 7]
                out.extend(st.unpack_from(data, 4 + off))
                off += size
            else:
                off += (-off) & 3
                (length,) = struct.unpack_from("<I", data, 4 + off)
                off += 4
                raw = bytes(data[4 + off : 4 + off + length])
                out.append(
                    raw[:-1].decode("utf-8") if length > 1 else (raw.rstrip(b"\0").decode("utf-8"))
                )
                off += length
        return tuple(out)

    def decode_columns(
        self, buf: bytes, count: int, sizes: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """Columns from ``count`` messages' data concatenated in ``buf`` (``sizes`` per message
        when the layout is variable)."""
        if self.fixed:
            if count == 0:
                return self.empty()
            arr = np.frombuffer(buf, dtype=self.dtype, count=count)
            return {n: np.ascontiguousarray(arr[n]) for n in self.names}
        rows = []
        mv = memoryview(buf)
        pos = 0
        for sz in sizes if sizes is not None else ():
            sz = int(sz)
            rows.append(self.decode(mv[pos : pos + sz]))
            pos += sz
        return self.columns_from_rows(rows)

    def columns_from_rows(self, rows: list[tuple]) -> dict[str, np.ndarray]:
        cols: dict[str, np.ndarray] = {}
        for j, f in enumerate(self.fields):
            vals = [r[j] for r in rows]
            if f.type == "string":
                a = np.empty(len(vals), dtype=object)
                a[:] = vals
                cols[f.name] = a
            else:
                cols[f.name] = np.array(vals, dtype=PRIMITIVES[f.type][2]).astype(
                    np.dtype(PRIMITIVES[f.type][2]).newbyteorder("=")
                )
        return cols

    def empty(self) -> dict[str, np.ndarray]:
        return {
            f.name: (
                np.empty(0, dtype=object)
                if f.type == "string"
                else np.empty(0, dtype=np.dtype(PRIMITIVES[f.type][2]).newbyteorder("="))
            )
            for f in self.fields
        }


_CODECS: dict[str, Codec] = {}


def codec_for(topic: str | TopicDef) -> Codec:
    """The (cached) codec of a known topic, or of a TopicDef."""
    if isinstance(topic, TopicDef):
        c = _CODECS.get(topic.topic)
        if c is None or c.topic != topic:
            c = Codec(topic)
            _CODECS[topic.topic] = c
        return c
    c = _CODECS.get(topic)
    if c is None:
        c = Codec(TOPICS[topic])
        _CODECS[topic] = c
    return c
