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
