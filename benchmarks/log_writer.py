"""Log writer throughput (the project's chunks, pmsm_hil.log.mcap_file, with its CDR codecs):
messages per second through LogWriter.write(), LogWriter.write_many() and
LogWriter.message_block() / write_block() (the run's recorder: a receive batch of 100 frames made at
once, written in runs of 20 between other messages), best and median of several runs, as a multiple of the fastest link's message rate
(docs/log-format.md, "Writing").

    python3 benchmarks/log_writer.py [--repeat 5] [--n 40000]

Link message rates, for profiles/paper-a.yaml (the defaults):
- serial 921.6 kbaud: the profile's telemetry rates (fast + params per estimator + status + truth),
  and the bound the link sets: its octets/s over the smallest frame;
- CAN 1 Mbit/s: the rates the profile runs at over CAN (transport.can_bus.apply_can_rates), and the
  bound: 8-octet CAN frames (111 bits) back to back, every logged message in the fewest frames any
  takes (2: an event; telemetry takes 4, firmware/proto/pmsm_proto.yaml, docs/can.md).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from pmsm_hil.log.blocks import cdr_from_columns
from pmsm_hil.log.schemas import TOPICS, codec_for
from pmsm_hil.log.writer import LogWriter
from pmsm_hil.profiles import load_profile
from pmsm_hil.profiles.profile import FRAME_OVERHEAD_OCTETS, OCTETS_PER_SYMBOL, PAYLOAD_OCTETS

ROOT = Path(__file__).resolve().parents[1]


def link_rates() -> dict[str, float]:
    """Messages/s of each link: the profile's rates and the bound of the link."""
    from pmsm_hil.device import apply_can_rates

    out = {}
    for kind in ("serial", "can"):
        p = load_profile(ROOT / "profiles" / "paper-a.yaml")
        if kind == "can":
            apply_can_rates(p)
        n_est = 4 if p.control.identify else 1
        t = p.telemetry
        out[f"{kind}, paper-a rates"] = t.fast_hz + n_est * t.params_hz + t.status_hz + t.truth_hz
    p = load_profile(ROOT / "profiles" / "paper-a.yaml")
    out["serial, bound (921.6 kbaud / smallest frame)"] = (
        p.link.baud / OCTETS_PER_SYMBOL / (min(PAYLOAD_OCTETS.values()) + FRAME_OVERHEAD_OCTETS)
    )
    out["CAN, bound (1 Mbit/s / two 111-bit frames)"] = 1e6 / (47 + 64) / 2
    return out


def bench(fn, n: int, repeat: int) -> tuple[float, float]:
    rates = []
    with tempfile.TemporaryDirectory() as d:
        for rep in range(repeat):
            t0 = time.perf_counter()
            fn(Path(d) / f"t{rep}.mcap")
            rates.append(n / (time.perf_counter() - t0))
    return max(rates), statistics.median(rates)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--n", type=int, default=40000)
    args = ap.parse_args()
    names = TOPICS["/pmsm/telemetry"].names[1:]
    rows = [{k: i * 1e-3 + j for j, k in enumerate(names)} for i in range(args.n)]
    cols = {"t_s": np.arange(args.n) * 5e-4}
    cols.update({k: np.array([r[k] for r in rows]) for k in names})
    codec = codec_for(TOPICS["/pmsm/telemetry"])

    def one_by_one(path):
        with LogWriter(path) as w:
            for i, r in enumerate(rows):
                w.write("/pmsm/telemetry", i * 5e-4, r)

    def in_bulk(path):
        with LogWriter(path) as w:
            w.write_many("/pmsm/telemetry", cols)

    def blocks(path):
        with LogWriter(path) as w:
            layout = w.fixed_layout("/pmsm/telemetry")
            assert layout is not None
            for at in range(0, len(rows), 100):  # receive batches of 100 frames
                batch = {k: v[at : at + 100] for k, v in cols.items()}
                data = cdr_from_columns("/pmsm/telemetry", codec, batch, len(batch["t_s"]))
                block = w.message_block("/pmsm/telemetry", batch["t_s"], data)
                for stop in range(20, len(block) + 20, 20):  # runs between params frames
                    w.write_block(block, min(stop, len(block)))

    def ros2_writer(path):
        # for comparison: mcap_ros2's writer, which encodes from dicts itself
        from mcap_ros2.writer import Writer as Ros2Writer

        td = TOPICS["/pmsm/telemetry"]
        with open(path, "wb") as f:
            w = Ros2Writer(f)
            schema = w.register_msgdef(td.schema_name, td.msgdef)
            for i, r in enumerate(rows):
                lt = round(i * 5e-4 * 1e9)
                w.write_message(
                    "/pmsm/telemetry", schema, {"t_s": i * 5e-4, **r}, log_time=lt, publish_time=lt
                )
            w.finish()

    results = {
        "LogWriter.write": bench(one_by_one, args.n, args.repeat),
        "LogWriter.write_many": bench(in_bulk, args.n, args.repeat),
        "LogWriter.write_block (the recorder's; encoding included)": bench(
            blocks, args.n, args.repeat
        ),
        "mcap_ros2 Writer (not used)": bench(ros2_writer, args.n, args.repeat),
    }
    links = link_rates()
    for label, (best, med) in results.items():
        print(
            f"{label}: best {best:,.0f} messages/s, median {med:,.0f} messages/s "
            f"({args.repeat} runs of {args.n} telemetry messages, zstd)"
        )
        for link, rate in links.items():
            print(
                f"  headroom over {link} ({rate:,.0f} messages/s): best {best / rate:.1f}x, "
                f"median {med / rate:.1f}x"
            )


if __name__ == "__main__":
    main()
