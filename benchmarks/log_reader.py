"""Log reading: the `mcap` library's readers against pmsm_hil.log.reader.read_log on a long log.

    python3 benchmarks/log_reader.py [--minutes 10] [--keep FILE]

Writes a log of paper-a's telemetry at the contract's fastest rates (telemetry 2 kHz, params
4 x 100 Hz, status 10 Hz, sim truth 100 Hz; chunks as the writer closes them), then reads the
telemetry topic's columns, each way in a fresh process (wall time and peak RSS):

- ``read_log``: the project's reader (its own scan of the top-level records, the chunks' message
  indexes as numpy arrays, a numpy gather and decode of the fixed-layout CDR data);
- ``records only``: only the library's StreamReader(emit_chunks=True) over the file: the
  top-level records parsed (chunks left compressed, every message-index entry a Python tuple), no
  message decoded: the least a reader built on the library's record parsing would cost;
- ``seeking+numpy``: mcap.reader.make_reader(...).iter_messages(topics=[...]) (through the
  summary's index), the data joined and decoded by numpy;
- ``stream+numpy``: mcap.stream_reader.StreamReader record by record (works on an unfinalised
  file), the data decoded by numpy;
- ``ros2 decoder``: mcap_ros2's iter_decoded_messages on the first 100 k messages (extrapolated).

and prints the extrapolation to one hour at 2 kHz (issue: analyze on such a log <= 8 s, <= 1 GiB).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

TEL = "/pmsm/telemetry"


def make_log(path: str, minutes: float) -> dict[str, int]:
    from pmsm_hil.log.schemas import TOPICS
    from pmsm_hil.log.writer import LogWriter

    rng = np.random.default_rng(1)
    counts = {t: 0 for t in (TEL, "/pmsm/params", "/pmsm/status", "/sim/truth")}
    rates = {TEL: 2000, "/pmsm/status": 10, "/sim/truth": 100}
    with LogWriter(path, {"run": {"profile": "paper-a"}}) as w:
        for sec in range(int(minutes * 60)):
            for topic, hz in rates.items():
                names = TOPICS[topic].names
                t = sec + np.arange(hz) / hz
                cols = {"t_s": t}
                for n, f in zip(names[1:], TOPICS[topic].fields[1:], strict=False):
                    if f.type == "string":
                        cols[n] = np.array(["running"] * hz, dtype=object)
                    elif f.type.startswith("float"):
                        cols[n] = rng.standard_normal(hz)
                    else:
                        cols[n] = np.arange(hz) % 7
                counts[topic] += w.write_many(topic, cols)
            for k in range(100):
                for est in ("nominal", "rls", "adaline", "nlms_adaline"):
                    w.write(
                        "/pmsm/params",
                        sec + k / 100,
                        {
                            "estimator": est,
                            "l_d_h": 1e-3,
                            "l_q_h": 2e-3,
                            "psi_f_wb": 0.1,
                            "r_s_ohm": 0.5,
                        },
                    )
                    counts["/pmsm/params"] += 1
    return counts


def _numpy_columns(datas: list[bytes]) -> dict:
    from pmsm_hil.log.schemas import codec_for

    codec = codec_for(TEL)
    return codec.decode_columns(b"".join(datas), len(datas))


def run_one(variant: str, path: str) -> dict:
    t0 = time.perf_counter()
    n = 0
    if variant == "read_log":
        from pmsm_hil.log.reader import read_log

        log = read_log(path)
        n = len(log.topic(TEL)["t_s"])
    elif variant == "records only":
        from mcap.records import MessageIndex
        from mcap.stream_reader import StreamReader

        with open(path, "rb") as f:
            for rec in StreamReader(f, emit_chunks=True).records:
                if isinstance(rec, MessageIndex):
                    n += len(rec.records)
    elif variant == "seeking+numpy":
        from mcap.reader import make_reader

        with open(path, "rb") as f:
            datas = [m.data for _, _, m in make_reader(f).iter_messages(topics=[TEL])]
        n = len(_numpy_columns(datas)["t_s"])
    elif variant == "stream+numpy":
        from mcap.records import Channel, Message
        from mcap.stream_reader import StreamReader

        datas, cid = [], None
        with open(path, "rb") as f:
            for rec in StreamReader(f).records:
                if isinstance(rec, Message):
                    if rec.channel_id == cid:
                        datas.append(rec.data)
                elif isinstance(rec, Channel) and rec.topic == TEL:
                    cid = rec.id
        n = len(_numpy_columns(datas)["t_s"])
    elif variant == "ros2 decoder":
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory

        vals = []
        with open(path, "rb") as f:
            for _, _, _, msg in make_reader(
                f, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages(topics=[TEL]):
                vals.append(msg.t_s)
                if len(vals) >= 100_000:
                    break
        n = len(vals)
    dt = time.perf_counter() - t0
    return {
        "variant": variant,
        "s": dt,
        "n": n,
        "rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--keep", help="write (or reuse) the log here")
    ap.add_argument("--one", nargs=2, metavar=("VARIANT", "PATH"), help=argparse.SUPPRESS)
    ap.add_argument(
        "--variants",
        help="comma-separated",
        default="read_log,records only,seeking+numpy,stream+numpy,ros2 decoder",
    )
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(*args.one)))
        return
    with tempfile.TemporaryDirectory() as d:
        path = args.keep or os.path.join(d, "long.mcap")
        if not os.path.exists(path):
            t0 = time.perf_counter()
            counts = make_log(path, args.minutes)
            print(
                f"log: {args.minutes:g} min, {sum(counts.values()):,} messages ({counts[TEL]:,} telemetry), "
                f"{os.path.getsize(path) / 2**20:.1f} MiB, written in {time.perf_counter() - t0:.1f} s"
            )
        n_tel = int(args.minutes * 60 * 2000)
        hour = 3600 * 2000 / n_tel
        for v in args.variants.split(","):
            out = subprocess.run(
                [sys.executable, __file__, "--one", v, path], capture_output=True, text=True
            )
            if out.returncode:
                print(f"{v}: failed\n{out.stderr}")
                continue
            r = json.loads(out.stdout)
            per_s = r["n"] / r["s"]
            whole = v != "ros2 decoder"  # the others read the whole log: scale by its length
            t_hour = r["s"] * hour if whole else 3600 * 2000 / per_s
            mem = (
                f"~{r['rss_mib'] * hour:.0f} MiB"
                if whole and v != "records only"
                else "(not scaled)"
            )
            print(
                f"{v:>13}: {r['n']:,} messages in {r['s']:.2f} s ({per_s:,.0f}/s), peak RSS "
                f"{r['rss_mib']:.0f} MiB; one hour at 2 kHz: ~{t_hour:.0f} s, {mem}"
            )


if __name__ == "__main__":
    main()
