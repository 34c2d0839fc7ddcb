"""Compare the device topics of two MCAP logs bit for bit.

    python -m tools.compare_device_logs [--common-fields] reference.mcap candidate.mcap

The device topics are what the firmware and the emulated plant produced (telemetry, parameters,
events, capture, plant truth); host-side topics (/pmsm/status, /host/*) carry wall-clock data and
are not compared. Numeric columns are compared as raw bytes (NaN payloads and signed zeros count),
strings by value; events the host wrote itself (kind "host") are left out. Exit 0 when identical, 1 with a list of the first differences otherwise.
With --common-fields, a field that one log has and the other has not (a field added to a message)
is named but not counted: the fields both have are compared.
"""

from __future__ import annotations

import sys

import numpy as np

from pmsm_hil.log.reader import read_log

DEVICE_TOPICS = ("/pmsm/telemetry", "/pmsm/params", "/pmsm/events", "/pmsm/capture", "/sim/truth")


def _column_diff(name: str, a: np.ndarray, b: np.ndarray) -> str | None:
    if a.shape != b.shape:
        return f"{name}: shape {a.shape} != {b.shape}"
    if a.dtype != b.dtype:
        return f"{name}: dtype {a.dtype} != {b.dtype}"
    if a.dtype.kind in "OUS":
        bad = [i for i, (x, y) in enumerate(zip(a.tolist(), b.tolist(), strict=False)) if x != y]
    else:
        av = np.ascontiguousarray(a).view(np.uint8).reshape(len(a), -1) if a.size else a
        bv = np.ascontiguousarray(b).view(np.uint8).reshape(len(b), -1) if b.size else b
        bad = np.nonzero(np.any(av != bv, axis=1))[0].tolist() if a.size else []
    if not bad:
        return None
    i = bad[0]
    return f"{name}: {len(bad)} of {len(a)} rows differ, first at row {i}: {a[i]!r} != {b[i]!r}"


def _device_rows(topic: str, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Drop the host's own entries in the event stream (kind "host": they name the port)."""
    if topic != "/pmsm/events" or "kind" not in cols:
        return cols
    keep = np.asarray(cols["kind"]) != "host"
    return {k: np.asarray(v)[keep] for k, v in cols.items()}


def compare(ref_path: str, new_path: str, common_fields: bool = False) -> list[str]:
    """Differences between the device topics of two logs (empty when bit-identical); with
    common_fields, only the fields both logs have are compared (the others are named in
    `compare.notes`)."""
    ref, new = read_log(ref_path), read_log(new_path)
    diffs: list[str] = []
    compare.notes = []  # type: ignore[attr-defined]
    for topic in DEVICE_TOPICS:
        in_ref, in_new = topic in ref.topics, topic in new.topics
        if in_ref != in_new:
            diffs.append(f"{topic}: present in {'reference' if in_ref else 'candidate'} only")
            continue
        if not in_ref:
            continue
        ta, tb = _device_rows(topic, ref.topic(topic)), _device_rows(topic, new.topic(topic))
        if sorted(ta) != sorted(tb):
            if not common_fields:
                diffs.append(f"{topic}: fields {sorted(ta)} != {sorted(tb)}")
                continue
            only = sorted(set(ta) ^ set(tb))
            compare.notes.append(f"{topic}: not compared, in one log only: {only}")  # type: ignore[attr-defined]
        for key in (k for k in ta if k in tb):
            d = _column_diff(f"{topic}.{key}", np.asarray(ta[key]), np.asarray(tb[key]))
            if d:
                diffs.append(d)
    return diffs


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    common = "--common-fields" in args
    args = [a for a in args if a != "--common-fields"]
    if len(args) != 2:
        print(
            "usage: python -m tools.compare_device_logs [--common-fields] REFERENCE.mcap "
            "CANDIDATE.mcap",
            file=sys.stderr,
        )
        return 2
    diffs = compare(args[0], args[1], common)
    for n in compare.notes:  # type: ignore[attr-defined]
        print(n)
    try:
        for d in diffs:
            print(d)
    except BrokenPipeError:  # the reader (head) has seen enough
        sys.stdout = None
        return 1
    if not diffs:
        print(f"identical: {', '.join(DEVICE_TOPICS)}")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
