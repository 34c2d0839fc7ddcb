"""`pmsm-hil log recover LOG.mcap [-o OUT.mcap]`: make the log of a killed run whole again."""

from __future__ import annotations

import argparse
from pathlib import Path

from pmsm_hil.cli.errors import fail


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("log", help="log file tools (recover a killed run's log)")
    lsub = p.add_subparsers(dest="log_command", required=True, metavar="TOOL")
    r = lsub.add_parser(
        "recover",
        help="rewrite a log whose writer was killed into a finalised one",
        description="Reads every message that reached the disk (the writer flushes a "
        "chunk at least every second of device time) and writes a "
        "finalised copy, with its index and summary, that any MCAP "
        "reader opens (Foxglove, the `mcap` library).",
    )
    r.add_argument("log", help="the MCAP log to recover")
    r.add_argument(
        "-o", "--out", default=None, help="the recovered log (default: LOG with .recovered.mcap)"
    )


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.log.reader import LogFormatError, rewrite_log

    src = Path(args.log)
    if not src.is_file():
        return fail("error", f"{src}: no such file", 2)
    if src.stat().st_size == 0:
        return fail("error", f"{src}: the file is empty (0 octets): nothing to recover", 2)
    dst = Path(args.out) if args.out else src.with_suffix(".recovered.mcap")
    if dst.resolve() == src.resolve():
        return fail("error", f"-o {dst}: give another file than the one being recovered", 2)
    try:
        dst.parent.mkdir(parents=True, exist_ok=True)
        log = rewrite_log(src, dst)
    except LogFormatError as e:
        return fail("error", str(e), 2)
    except OSError as e:
        return fail("error", f"-o {dst}: cannot write ({e.strerror or e})", 2)
    state = "finalised" if log.finalised else ("truncated" if log.truncated else "not finalised")
    total = sum(log.counts.values())
    print(f"{src} ({state}): {total} messages in {len(log.topics)} topics recovered -> {dst}")
    for p in log.problems:
        print(f"  {p}")
    return 0
