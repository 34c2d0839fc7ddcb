"""A log read once for the run summary and the identification table together: only the topics
and fields they use are decoded (pmsm_hil.log.reader, ``topics=``)."""

from __future__ import annotations

import os
from pathlib import Path

from pmsm_hil.analysis.identification import IDENT_TOPICS
from pmsm_hil.analysis.summary import SUMMARY_TOPICS
from pmsm_hil.log.reader import Log, merge_topics, read_log

ANALYSIS_TOPICS = merge_topics(SUMMARY_TOPICS, IDENT_TOPICS)


def read_for_analysis(path: str | os.PathLike) -> Log:
    """The log at ``path`` with what summarize_log and identification_table read; raises
    LogFormatError (not MCAP) or ValueError (an empty file)."""
    if Path(path).stat().st_size == 0:
        raise ValueError(f"{path}: the file is empty (0 octets): no run was recorded")
    return read_log(path, topics=ANALYSIS_TOPICS)


def recover_hint(path: str | os.PathLike) -> str:
    """``"; LOG.journal is beside it: `pmsm-hil log recover LOG` adds ..."`` when the log of a
    killed run has its journal beside it (docs/faults.md), else ``""``: for the messages of
    `analyze` and `report` about a log cut short."""
    journal = Path(f"{os.fspath(path)}.journal")
    if not journal.is_file():
        return ""
    return (
        f"; {journal.name} is beside it: `pmsm-hil log recover {os.fspath(path)}` adds what the "
        "host received after the last chunk"
    )


def other_kind(log: Log) -> str | None:
    """Why ``log`` is not a profile run that `analyze` and `report` judge (None when it is):
    another program's MCAP file (no topic of pmsm-hil's), an imported record (control-rate data
    only, `pmsm-hil import`) or a commissioning run (its results are the commissioned motor
    file's)."""
    topics = set(log.topics)
    if topics and not any(t.startswith(("/pmsm/", "/sim/")) for t in topics):
        shown = ", ".join(sorted(topics)[:5]) + (", ..." if len(topics) > 5 else "")
        return (
            f"an MCAP file of another program (topics: {shown}), not a pmsm-hil log: "
            "`pmsm-hil run` writes /pmsm/telemetry, /pmsm/events ... (docs/log-format.md)"
        )
    if "/pmsm/control_rate" in topics and "/pmsm/telemetry" not in topics:
        return (
            "an imported control-rate record (pmsm-hil import), not a profile run: diagnose it "
            "with `pmsm-hil gap LOG` (docs/gap.md)"
        )
    if "/pmsm/commission" in topics:
        return (
            "a commissioning run (pmsm-hil commission), not a profile run: its results are in the "
            "commissioned motor file's `commissioning:` section (docs/commissioning.md)"
        )
    return None
