"""Link use and host headroom, serial (921.6 kbaud) and CAN (1 Mbit/s), on the emulator (docs/can.md).

    python3 benchmarks/link.py

Link use: the telemetry delivered per second over a full profiles/paper-a.yaml run, as a share of
what the link can carry (its bit rate): `wire` counts the stream's frames as they occupy the line
(serial: 10 bits per octet incl. id, seq, CRC, COBS and delimiter; CAN: every frame bit incl. stuff
bits of the actual content, as the sim board counts them), `payload` only the messages' payload
octets. Two plans per link: the nominal one (the profile's rates for that link) and the fast stream
at full rate (serial: 2.5 kHz; CAN: the planner's highest telem_fast rate, `can_fast_hz_max`; sim_truth lowered to 20 Hz). Every run must
lose nothing: no sequence gap on the host and no frame dropped in the firmware (status.tx_dropped).

Host headroom: the recorded link data of the nominal run replayed through the host's decoder, the
recorder and the MCAP writer, in frames per second, as a multiple of the most frames the link can
carry per second (serial: telem_fast frames at 921.6 kbaud; CAN: 8-octet frames at 1 Mbit/s).
"""

from __future__ import annotations

import ctypes
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pmsm_hil.device import apply_can_rates, inprocess_can_link  # noqa: E402
from pmsm_hil.emulator.fwlib import lib  # noqa: E402
from pmsm_hil.emulator.settings import emulator_settings  # noqa: E402
from pmsm_hil.log.writer import LogWriter  # noqa: E402
from pmsm_hil.profiles import load_profile  # noqa: E402
from pmsm_hil.protocol import codec  # noqa: E402
from pmsm_hil.protocol import generated as gen  # noqa: E402
from pmsm_hil.protocol.can_link import CanDecoder, can_fast_hz_max  # noqa: E402
from pmsm_hil.protocol.session import Session  # noqa: E402
from pmsm_hil.recorder import Recorder  # noqa: E402
from pmsm_hil.runner import RunOptions, run_profile  # noqa: E402
from pmsm_hil.transport.inproc import InProcessTransport  # noqa: E402

PROFILE = ROOT / "profiles" / "paper-a.yaml"
STREAMS = ("telem_fast", "params", "status", "sim_truth")


def frame_bits(ident: int, data: bytes) -> int:
    so = lib()
    so.can_frame_bits.restype = ctypes.c_uint32
    so.can_frame_bits.argtypes = [ctypes.c_uint16, ctypes.POINTER(ctypes.c_uint16), ctypes.c_uint16]
    arr = (ctypes.c_uint16 * 8)(*data)
    return so.can_frame_bits(ident, arr, len(data))


class Recording(InProcessTransport):
    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.chunks: list[bytes] = []

    def read(self, timeout_s):
        out = super().read(timeout_s)
        if out:
            self.chunks.append(out)
        return out


def run(link_kind: str, full_rate: bool, tmp: Path):
    profile = load_profile(str(PROFILE))
    if link_kind == "can":
        apply_can_rates(profile)
    if full_rate:
        tel = profile.telemetry
        if link_kind == "serial":
            fast = 2500.0
        else:  # the CAN planner's highest rate next to the other streams (sim_truth at 20 Hz)
            others = {"params": tel.params_hz, "status": tel.status_hz, "sim_truth": 20.0}
            fast = can_fast_hz_max(others, profile.control.ts_s)
        profile.telemetry = tel.model_copy(update={"fast_hz": fast, "truth_hz": 20.0})
    settings = emulator_settings(
        profile.motor,
        profile.rig,
        seed=1,
        baud=profile.link.baud,
        ts_s=profile.control.ts_s,
        truth_hz=profile.telemetry.truth_hz,
    )
    if link_kind == "serial":
        link = Recording(settings)
    else:
        link = inprocess_can_link(settings)
        link.bus.recorded = []
    t0 = time.perf_counter()
    result = run_profile(
        profile,
        Session(link),
        tmp / f"{link_kind}-{full_rate}.mcap",
        RunOptions(seed=1, capture=not full_rate),
    )
    wall = time.perf_counter() - t0
    t_run = profile.total_duration_s
    lost = result.live.seq_gaps + int(result.live.status.get("tx_dropped", 0))
    payload = Counter()
    wire_bits = Counter()
    count = Counter()
    if link_kind == "serial":
        dec = codec.FrameDecoder()
        for msg_id, _seq, p in dec.feed_raw(b"".join(link.chunks)):
            name = gen.BY_ID[msg_id].name
            count[name] += 1
            payload[name] += len(p)
            wire_bits[name] += 10 * (len(p) + 6)
        capacity = profile.link.baud
        replay = b"".join(link.chunks)
    else:
        from pmsm_hil.protocol import can_generated as cg

        by_func = {f: gen.BY_ID[m].name for f, (m, _k) in cg.BY_FUNC.items()}
        for t, ident, data in link.bus.recorded:
            if t > t_run + 0.5:
                continue
            name = by_func.get(ident >> 4, "transfer")
            wire_bits[name] += frame_bits(ident, data)
        for fr in CanDecoder().feed([(i, d) for _t, i, d in link.bus.recorded]):
            count[fr.name] += 1
            payload[fr.name] += gen.BY_NAME[fr.name].length
        capacity = profile.link.can.bitrate
        replay = [(i, d) for _t, i, d in link.bus.recorded]
    return dict(
        profile=profile,
        result=result,
        wall=wall,
        t=t_run,
        lost=lost,
        payload=payload,
        wire_bits=wire_bits,
        count=count,
        capacity=capacity,
        replay=replay,
    )


def headroom(link_kind: str, r: dict, tmp: Path) -> tuple[float, float, float]:
    """(frames/s through decode + recorder + MCAP, link's max frames/s, ratio)."""
    profile = r["profile"]
    names = [s.name or f"segment {i}" for i, s in enumerate(profile.segments)]
    writer = LogWriter(tmp / f"replay-{link_kind}.mcap", {"run": {}, "device": {}}, [])
    rec = Recorder(writer, profile.control.ts_s, names)
    t0 = time.perf_counter()
    if link_kind == "serial":
        dec = codec.FrameDecoder()
        data = r["replay"]
        n = 0
        for at in range(0, len(data), 65536):
            frames = dec.feed(data[at : at + 65536])
            n += len(frames)
            rec.frames(frames)
        link_max = profile.link.baud / 10 / (gen.BY_NAME["telem_fast"].length + 6)
    else:
        dec = CanDecoder()
        frames_in = r["replay"]
        for at in range(0, len(frames_in), 4096):
            rec.frames(dec.feed(frames_in[at : at + 4096]))
        n = len(frames_in)  # CAN frames
        link_max = profile.link.can.bitrate / (47 + 64)
    writer.close()
    rate = n / (time.perf_counter() - t0)
    return rate, link_max, rate / link_max


def main() -> int:
    ok = True
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        print(
            f"{'link':<22} {'plan':<10} {'fast Hz':>8} {'fast wire':>10} {'fast payload':>13} "
            f"{'all telemetry wire':>19} {'lost':>5} {'run':>14}"
        )
        nominal = {}
        for kind, label in (("serial", "serial 921.6 kbaud"), ("can", "CAN 1 Mbit/s")):
            for full in (False, True):
                r = run(kind, full, tmp)
                if not full:
                    nominal[kind] = r
                cap, t = r["capacity"], r["t"]
                fast_wire = r["wire_bits"]["telem_fast"] / t / cap
                fast_payload = 8 * r["payload"]["telem_fast"] / t / cap
                tel_wire = sum(r["wire_bits"][s] for s in STREAMS) / t / cap
                res = r["result"]
                fine = res.state == "done" and r["lost"] == 0
                ok &= fine
                print(
                    f"{label:<22} {'full rate' if full else 'nominal':<10} "
                    f"{r['profile'].telemetry.fast_hz:8.1f} {100 * fast_wire:9.1f}% {100 * fast_payload:12.1f}% "
                    f"{100 * tel_wire:18.1f}% {r['lost']:5d} {t:6.2f} s {r['wall']:5.1f} s"
                    + ("" if fine else f"  FAILED ({res.state}, {res.stop_reason})")
                )
        print()
        for kind, label, unit in (
            ("serial", "serial 921.6 kbaud", "messages"),
            ("can", "CAN 1 Mbit/s", "CAN frames"),
        ):
            rate, link_max, ratio = headroom(kind, nominal[kind], tmp)
            print(
                f"host headroom {label:<20} decode + recorder + MCAP {rate:9.0f} {unit}/s, link max "
                f"{link_max:6.0f}/s: {ratio:5.1f}x"
            )
            ok &= ratio >= 10
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
