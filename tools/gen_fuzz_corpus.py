"""Seed corpus of the whole-firmware fuzz target (firmware/fuzz/fuzz_fw.c): real sessions as the
target's operations. Each seed is what the host sends for a shipped profile (hello, the
configuration, the profile, start), then control periods with a heartbeat every 20 ms for a
while, then silence; one seed also stops and one aborts. Written to
firmware/fuzz/corpus/fuzz_fw/.

    python -m tools.gen_fuzz_corpus
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import codec
from pmsm_hil.protocol import generated as gen
from pmsm_hil.runner import configure

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "firmware" / "fuzz" / "corpus" / "fuzz_fw"
PROFILES = ("paper-a.yaml", "paper-a-sensorless.yaml", "paper-b.yaml", "commission.yaml")


class Recorder:
    """Stands in for a Session: what `configure` would request, in order."""

    def __init__(self) -> None:
        self.sent: list[tuple[str, dict[str, Any]]] = []
        self.identity = None

    def request(self, name: str, **fields: Any) -> None:
        self.sent.append((name, fields))


def frame_op(name: str, seq: int, fields: dict[str, Any]) -> bytes:
    """The target's well-formed-frame operation for one message."""
    spec = gen.BY_NAME[name]
    payload = codec.encode_payload(spec.id, **fields)
    return bytes([0x40 + (seq % 0x80), spec.id]) + bytes(payload)


def session_ops(profile_name: str, end: str) -> bytes:
    profile = load_profile(ROOT / "profiles" / profile_name)
    rec = Recorder()
    rec.request("hello", host_proto_version=gen.PROTOCOL_VERSION)
    configure(rec, profile)  # type: ignore[arg-type]
    rec.request("start")
    ops = b"".join(frame_op(n, k, f) for k, (n, f) in enumerate(rec.sent))
    ticks_20ms = round(0.02 / profile.control.ts_s)
    for k in range(10):  # 0.2 s running with heartbeats
        ops += bytes([0xC0 + ticks_20ms // 16 - 1]) + frame_op("heartbeat", k, {"counter": k})
    if end in ("stop", "abort"):
        ops += frame_op(end, 99, {})
    return ops


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    for p in PROFILES:
        stem = p.removesuffix(".yaml")
        (OUT / f"{stem}-silent").write_bytes(session_ops(p, "silent"))
    (OUT / "paper-a-stop").write_bytes(session_ops("paper-a.yaml", "stop"))
    (OUT / "paper-a-abort").write_bytes(session_ops("paper-a.yaml", "abort"))
    print(f"{len(list(OUT.iterdir()))} seeds in {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
