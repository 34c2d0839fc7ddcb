"""`pmsm-hil log recover LOG.mcap [-o OUT.mcap]`: make the log of a killed run whole again."""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.cli.errors import fail
from pmsm_hil.cli.paths import write_problem

if TYPE_CHECKING:  # the reader (numpy, mcap) is imported when a command runs
    from pmsm_hil.log.reader import Log


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("log", help="log file tools (recover a killed run's log)")
    lsub = p.add_subparsers(dest="log_command", required=True, metavar="TOOL")
    r = lsub.add_parser(
        "recover",
        help="rewrite a log whose writer was killed into a finalised one",
        description="Reads every message that reached the disk (a run's log and its journal "
        "LOG.journal, to which each batch of received messages goes at its end) and writes a "
        "finalised copy, with its index and summary, that any MCAP "
        "reader opens (Foxglove, the `mcap` library). Reports per topic what was recovered "
        "(messages, device-time span) and what the kill may have cost.",
    )
    r.add_argument("log", help="the MCAP log to recover")
    r.add_argument(
        "-o", "--out", default=None, help="the recovered log (default: LOG with .recovered.mcap)"
    )
    r.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a file already at the recovered log's path",
    )


def plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.log.journal import journal_path, read_journal
    from pmsm_hil.log.reader import LogFormatError, path_problem, read_log, rewrite_log

    src = Path(args.log)
    why = path_problem(args.log)
    if why:
        return fail("error", why, 2)
    if src.stat().st_size == 0:
        return fail("error", f"{src}: the file is empty (0 octets): nothing to recover", 2)
    dst = Path(args.out) if args.out else src.with_suffix(".recovered.mcap")
    if dst.resolve() == src.resolve():
        return fail("error", f"-o {dst}: give another file than the one being recovered", 2)
    if dst.resolve() == Path(journal_path(src)).resolve():  # read while written over: lost
        return fail("error", f"-o {dst}: give another file than the journal being recovered", 2)
    why = write_problem(dst, "-o", args.overwrite)  # another run's log, an earlier recovery
    if why:
        return fail("error", why, 2)
    try:  # what there is to recover, before anything is written (the counts: nothing decoded)
        head = read_log(src, topics=[])
    except LogFormatError as e:
        return fail("error", str(e), 2)
    held = sum(head.counts.values())
    late = len(read_journal(src, held))  # received after the last chunk: in the journal only
    if held + late == 0:
        cut = ", it ends inside a record" if head.truncated else ""
        return fail(
            "error",
            f"{src}: nothing to recover: not one complete chunk of messages "
            f"({src.stat().st_size} octets{cut}) and no messages in a journal "
            f"{journal_path(src)} beside it; nothing written",
            2,
        )
    try:
        dst.parent.mkdir(parents=True, exist_ok=True)
        log = rewrite_log(src, dst)
    except LogFormatError as e:
        return fail("error", str(e), 2)
    except OSError as e:
        return fail("error", f"-o {dst}: cannot write ({e.strerror or e})", 2)
    state = "finalised" if log.finalised else ("truncated" if log.truncated else "not finalised")
    total = sum(log.counts.values())
    print(
        f"{src} ({state}): {plural(total, 'message')} in {plural(len(log.topics), 'topic')} "
        f"recovered -> {dst}"
    )
    for line in recovered_lines(log, dst):
        print(f"  {line}")
    if head.finalised and not late:
        print(
            f"note: {src} was finalised (its run ended and closed it) and no journal adds to it: "
            "nothing was missing; the copy holds the same messages"
        )
    return 0


def recovered_lines(log: Log, dst: Path) -> list[str]:
    """Per topic: messages and device-time span; that dst holds exactly them; the loss bound."""
    from pmsm_hil.log.journal import journal_path, read_journal
    from pmsm_hil.log.reader import read_log

    out = []
    t_end, t_start = 0.0, float("inf")
    for topic in sorted(log.topics):
        t = log.topic(topic)["t_s"]
        if len(t):
            t_end = max(t_end, float(t[-1]))
            t_start = min(t_start, float(t[0]))
            out.append(f"{topic}: {plural(len(t), 'message')}, t = {t[0]:.4f} .. {t[-1]:.4f} s")
        else:
            out.append(f"{topic}: 0 messages")
    span = f"t = {t_start:.4f} .. {t_end:.4f} s" if t_start <= t_end else "no device time"
    out += [str(p) for p in log.problems]
    journal = read_journal(log.path, sum(log.counts.values()))
    want = dict(log.counts)
    for m in journal:
        want[m.topic] = want.get(m.topic, 0) + 1
    if journal:
        t_j = max((m.log_time for m in journal), default=0)
        off = int(log.metadata.get("log", {}).get("log_time_offset_ns", "0") or 0)
        out.append(
            f"{journal_path(log.path)}: {plural(len(journal), 'more message')}, received after "
            f"the last chunk, up to t = {(t_j - off) / 1e9:.4f} s"
        )
    written = read_log(dst, topics=[]).counts  # from the message indexes: nothing decoded
    missing = {k: v - written.get(k, 0) for k, v in want.items() if written.get(k, 0) != v}
    if missing:
        out.append(f"not rewritten: {missing}")
    else:
        out.append(f"{dst}: all {plural(sum(written.values()), 'message')} rewritten, finalised")
    meta = log.metadata.get("log", {})
    if not log.finalised:
        wall, chunk_s = meta.get("flush_wall_s"), meta.get("chunk_span_s", "1.0")
        if meta.get("journal") == "true" and not os.path.isfile(journal_path(log.path)):
            out.append(
                f"lost: everything after the last complete chunk (t = {t_end:.4f} s): the log "
                f"was written with a journal, which held what the host received after that "
                f"chunk, but {journal_path(log.path)} is not beside it; the recovered part "
                f"covers {span} of device time"
            )
        elif wall and meta.get("journal") == "true":
            out.append(
                "lost: none of the device's messages the host had received (each receive batch "
                "went to the journal at its end); of the host's own messages (events) at most "
                f"those of its last {float(wall):g} s of wall time before it was killed"
            )
        elif meta.get("sync") == "batch":
            out.append(
                "lost: nothing the host had received: each batch read from the link was on disk "
                f"before the next read (the log ends at t = {t_end:.4f} s)"
            )
        elif wall:
            out.append(
                f"lost: at most what the host received in the last {float(wall):g} s of wall time "
                f"before it was killed (never more than {float(chunk_s):g} s of device time) after "
                f"t = {t_end:.4f} s"
            )
        else:
            out.append(
                f"lost: at most the last {float(chunk_s):g} s of device time after t = "
                f"{t_end:.4f} s"
            )
        if log.truncated and meta.get("journal") != "true":  # (the journal's case: above)
            out.append(
                "the file ends inside a record: if it was cut short (a partial copy) rather than "
                f"its writer killed, everything after t = {t_end:.4f} s is lost; the recovered "
                f"part covers {span} of device time"
            )
    return out
