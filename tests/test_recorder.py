"""The recorder writes the busiest device messages straight from their payload octets: the log and
the live state are those of the frame handlers (the path taken when a sink wants the fields)."""

from __future__ import annotations

import random

from pmsm_hil.log.reader import read_log
from pmsm_hil.log.writer import LogWriter
from pmsm_hil.protocol import codec
from pmsm_hil.protocol import generated as gen
from pmsm_hil.recorder import Recorder

TS_S = 50e-6


def _value(rnd: random.Random, f) -> float | int:
    _code, _size, lo, hi = gen.WIRE_TYPES[f.type]
    if lo is None:  # a float on the wire
        return rnd.uniform(-1e3, 1e3)
    lo_si = lo * (f.scale or 1)
    hi_si = hi * (f.scale or 1)
    return rnd.uniform(lo_si, hi_si) if f.scale else rnd.randint(lo, hi)


def _stream(n: int) -> bytes:
    """A device's output: telemetry every period, truth, the estimators' parameters (the three
    estimators and a code the host does not know, in turn or in a row) and status now and then,
    events."""
    rnd = random.Random(5)
    out = []
    seq = 0
    for k in range(n):
        names = ["telem_fast"]
        if k % 20 == 3:
            names.append("sim_truth")
        if k % 20 == 5:
            names += ["params"] * (1 + (k // 20) % 3)
        if k % 200 == 7:
            names.append("status")
        if k % 500 == 11:
            names.append("event")
        for name in names:
            spec = gen.BY_NAME[name]
            fields = {f.name: _value(rnd, f) for f in spec.fields}
            fields["tick"] = 3 * k
            if name == "status":
                fields["state"] = 1
            if name == "event":
                fields["code"], fields["arg"] = 1, 0
            if name == "params":
                fields["estimator"] = (1, 2, 3, 1, 9)[rnd.randrange(5)]
            out.append(codec.encode(name, seq, **fields))
            seq = (seq + 1) & 0xFF
    return b"".join(out)


class _Sink:
    def __init__(self) -> None:
        self.n = 0

    def publish(self, topic: str, t_s: float, fields: dict) -> None:
        self.n += 1


def test_direct_path_writes_what_the_handlers_write(tmp_path):
    data = _stream(3000)
    logs, lives = [], []
    for label, sinks in (("direct", []), ("handlers", [_Sink()])):
        path = tmp_path / f"{label}.mcap"
        with LogWriter(path, {"run": {}}, journal=True) as w:
            rec = Recorder(w, TS_S, ["a", "b"], sinks)
            dec = codec.FrameDecoder()
            for at in range(0, len(data), 1000):
                rec.frames(dec.feed(data[at : at + 1000]))
        logs.append(path.read_bytes())
        lives.append(rec.live)
    assert logs[0] == logs[1]
    a, b = lives
    assert (a.t_s, a.frames, a.seq_gaps, a.telemetry, a.truth, a.status, a.params) == (
        b.t_s,
        b.frames,
        b.seq_gaps,
        b.telemetry,
        b.truth,
        b.status,
        b.params,
    )
    assert set(a.params) == {"rls", "adaline", "nlms_adaline", "9"}
    log = read_log(tmp_path / "direct.mcap")
    assert log.counts["/pmsm/telemetry"] == 3000
    assert log.counts["/sim/truth"] == 150
    assert log.counts["/pmsm/params"] == 300
    # the parameters and the flags' bits as the device sent them
    sent = [fr.fields for fr in codec.FrameDecoder().feed(data) if fr.name == "params"]
    params = log.topic("/pmsm/params")
    names = {1: "rls", 2: "adaline", 3: "nlms_adaline"}
    assert list(params["estimator"]) == [names.get(f["estimator"], "9") for f in sent]
    assert list(params["l_q_h"]) == [f["l_q_h"] for f in sent]
    for field, bit in (("excited", 1), ("converged", 2), ("feeds_predictor", 4)):
        assert list(params[field]) == [bool(f["flags"] & bit) for f in sent]


def test_frames_decode_their_fields_when_asked():
    frame = codec.encode("event", 4, tick=10, code=1, arg=-3)
    (fr,) = codec.FrameDecoder().feed(frame)
    assert (fr.msg_id, fr.seq, fr.name) == (gen.BY_NAME["event"].id, 4, "event")
    assert fr.fields == {"tick": 10, "code": 1, "arg": -3}
    msg_id, seq, name, fields = fr
    assert fr == codec.Frame(msg_id, seq, name, fields)


def _event_texts(tmp_path, events: list[tuple[str, int]]) -> list[str]:
    """The text the recorder gives each device event (code by name, arg), in the log and live."""
    data = b"".join(
        codec.encode("event", k, tick=10 * k, code=gen.ENUMS["event"][name], arg=arg)
        for k, (name, arg) in enumerate(events)
    )
    with LogWriter(tmp_path / "ev.mcap", {"run": {}}) as w:
        rec = Recorder(w, TS_S, ["a"])
        rec.frames(codec.FrameDecoder().feed(data))
    logged = list(read_log(tmp_path / "ev.mcap").topic("/pmsm/events")["text"])
    assert logged == [e[3] for e in rec.live.events]
    return logged


def test_sensorless_and_identification_events_say_their_result(tmp_path):
    # the arg carries the result (firmware/proto/pmsm_proto.yaml): the text names it, so that the
    # live view and the log say which pole the polarity test found, at what speed the I/f start
    # handed over, what R the injection found
    texts = _event_texts(
        tmp_path,
        [
            ("polarity", 1),
            ("polarity", 2),
            ("polarity", 3),
            ("polarity", 4),
            ("polarity_asym", -2716),
            ("if_handover", 3124),
            ("if_failed", 0),
            ("r_identified", 1170),
        ],
    )
    assert texts[0].startswith("polarity: kept")
    assert texts[1].startswith("polarity: flipped")
    assert texts[2].startswith("polarity: not resolved")
    assert texts[3].startswith("polarity: no lock at rest")
    assert "-0.2716" in texts[4]
    assert "312.4 r/min" in texts[5]
    assert texts[6].startswith("I/f start failed")
    assert "1.170 ohm" in texts[7]
