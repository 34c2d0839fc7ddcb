"""The results of a sweep: a journal of finished runs (OUT/results.jsonl, one JSON row per line,
appended and flushed as each run ends, so an interrupted sweep loses nothing it finished) and the
table made from it (OUT/results.parquet and OUT/results.csv, one row per run of the plan).

Rows are keyed by the run's inputs (``Run.key``: a hash of its profile, motor and rig texts and its
seed); a resumed sweep skips the keys whose latest row has status "ok".
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

__all__ = [
    "FIRST_COLUMNS",
    "LAST_COLUMNS",
    "META_FORMAT",
    "Journal",
    "ResultsFormatError",
    "check_resumable",
    "has_criteria",
    "passed",
    "read_meta",
    "read_table",
    "write_meta",
    "write_table",
]

FIRST_COLUMNS = ("index", "key", "status", "seed")
LAST_COLUMNS = ("state", "stop_reason", "log_path", "error", "acceptance_checks", "wall_s")
# OUT/sweep.json's format: 2 since a relative axis has a factor column (``motor_r_s_factor``) and
# its absolute value under the field's name (``motor_r_s_ohm``, ohms); format 1 (no "format" key)
# held the factor under the field's name
META_FORMAT = 2


class ResultsFormatError(Exception):
    """A results directory this pmsm-hil cannot read or resume (the message names the file)."""


class Journal:
    def __init__(self, out: Path, filename: str = "results.jsonl"):
        self.path = Path(out) / filename
        self.rows: dict[str, dict[str, Any]] = {}
        if self.path.exists():
            with open(self.path, encoding="utf-8") as f:
                for line in f:
                    line = line.strip()
                    if not line:
                        continue
                    try:
                        row = json.loads(line)
                    except json.JSONDecodeError:
                        continue  # a line cut short by a kill: that run is simply redone
                    self.rows[row["key"]] = row

    def done(self) -> set[str]:
        return {k for k, r in self.rows.items() if r.get("status") == "ok"}

    def add(self, row: dict[str, Any]) -> None:
        self.rows[row["key"]] = row
        with open(self.path, "a", encoding="utf-8") as f:
            # in the row's own order (not sorted): a table written from the journal (a resumed
            # sweep) has its columns where a fresh sweep's are
            f.write(json.dumps(row) + "\n")
            f.flush()


def _columns(rows: list[dict[str, Any]], axes: list[str]) -> list[str]:
    seen: dict[str, None] = {}
    for r in rows:
        for k in r:
            seen.setdefault(k, None)
    rest = [k for k in seen if k not in FIRST_COLUMNS and k not in LAST_COLUMNS and k not in axes]
    return (
        [c for c in FIRST_COLUMNS if c in seen]
        + [a for a in axes if a in seen]
        + rest
        + [c for c in LAST_COLUMNS if c in seen]
    )


def _column_values(rows: list[dict[str, Any]], col: str) -> list[Any]:
    vals = [r.get(col) for r in rows]
    kinds = {type(v) for v in vals if v is not None}
    if kinds and kinds <= {int, float} and float in kinds:
        return [None if v is None else float(v) for v in vals]
    if len(kinds) > 1:
        return [None if v is None else str(v) for v in vals]
    return vals


def write_table(out: Path, rows: Iterable[dict[str, Any]], axes: list[str]) -> tuple[Path, Path]:
    """Write OUT/results.parquet and OUT/results.csv (rows sorted by run index)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    rows = sorted(rows, key=lambda r: r.get("index", 0))
    cols = _columns(rows, axes)
    table = pa.table({c: _column_values(rows, c) for c in cols}) if rows else pa.table({})
    pq_path, csv_path = Path(out) / "results.parquet", Path(out) / "results.csv"
    pq.write_table(table, pq_path)
    pacsv.write_csv(table, csv_path)
    return pq_path, csv_path


def read_table(out: Path) -> list[dict[str, Any]]:
    """The rows of OUT/results.parquet as dicts (NaN for a missing number)."""
    import pyarrow.parquet as pq

    rows = pq.read_table(Path(out) / "results.parquet").to_pylist()
    for r in rows:
        for k, v in r.items():
            if v is None and k not in FIRST_COLUMNS + LAST_COLUMNS:
                r[k] = math.nan
    return rows


def _nan(x: Any) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def passed(row: dict[str, Any]) -> bool:
    """The run completed (status ok), played the whole profile without a fault and met the
    profile's acceptance criteria (``acceptance_failed`` 0; a row without criteria: the first
    three alone)."""
    if row.get("status") != "ok":
        return False
    if row.get("complete") is False or (row.get("faults") or 0) > 0:
        return False
    return _nan(row.get("acceptance_failed")) or row["acceptance_failed"] == 0


def has_criteria(rows: Iterable[dict[str, Any]]) -> bool:
    """Whether any completed run was judged against acceptance criteria of its profile."""
    return any(not _nan(r.get("acceptance_failed")) for r in rows)


def write_meta(out: Path, name: str, file: str, profile: str, axes: list) -> None:
    """OUT/sweep.json: the sweep's name, files and axes (``Axis``) with their results columns."""
    meta = {
        "format": META_FORMAT,
        "name": name,
        "file": file,
        "profile": profile,
        "axes": [
            {
                "column": a.column,
                "value_column": a.name if a.relative else None,
                "field": a.field,
                "kind": a.kind,
                "relative": a.relative,
            }
            for a in axes
        ],
    }
    (Path(out) / "sweep.json").write_text(json.dumps(meta, indent=1) + "\n")


def read_meta(out: Path, rows: list[dict[str, Any]]) -> tuple[dict[str, Any], list[str]]:
    """OUT/sweep.json (absent: no axes) with every axis's ``column`` and ``value_column``, and
    notes for the reader. A format-1 directory (an older pmsm-hil) held a relative axis's factor
    under the field's name: its rows get the column renamed to the factor's, in place (the files
    stay as they are), and a note says so."""
    from .spec import factor_column

    path = Path(out) / "sweep.json"
    if not path.is_file():
        return {"axes": []}, []
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
        axes = meta["axes"]
        fmt = meta.get("format", 1)
    except (ValueError, KeyError, TypeError) as e:
        raise ResultsFormatError(
            f"{path}: not a sweep's sweep.json ({type(e).__name__}: {e})"
        ) from None
    if not isinstance(fmt, int) or fmt > META_FORMAT:
        raise ResultsFormatError(
            f"{path}: format = {fmt!r} is not one this pmsm-hil reads (1 to {META_FORMAT}); "
            "a newer pmsm-hil wrote it?"
        )
    notes: list[str] = []
    if fmt == 1:
        renamed = []
        for a in axes:
            a["column"], a["value_column"] = a["name"], None
            if a.get("relative"):
                a["column"] = factor_column(a["name"])
                renamed.append(f"{a['name']} as {a['column']}")
                for r in rows:
                    if a["name"] in r:
                        r[a["column"]] = r.pop(a["name"])
        notes.append(
            f"{path}: written by an older pmsm-hil (format 1)"
            + (
                ": the relative axes' columns hold factors, read here " + ", ".join(renamed)
                if renamed
                else ""
            )
            + "; its speed_error_max_rpm, ripple_d_max_a and ripple_q_max_a leave out the "
            "segments at standstill. Sweep into a new folder for the absolute values and "
            "today's definitions."
        )
    return meta, notes


def check_same_sweep(out: Path, name: str) -> None:
    """Raise ResultsFormatError when ``out`` holds another sweep's results (its sweep.json names
    another sweep): the table would be replaced and the two journals mixed. The same sweep, edited
    (an axis added, more draws), resumes: its unchanged runs keep their keys."""
    meta = Path(out) / "sweep.json"
    if not meta.is_file():
        return
    try:
        old = json.loads(meta.read_text(encoding="utf-8"))
        old_name, old_file = old.get("name"), old.get("file", "?")
    except (ValueError, AttributeError):
        return  # check_resumable says what is wrong with it
    if old_name is not None and old_name != name:
        raise ResultsFormatError(
            f"{meta}: name = {old_name!r}: {out} holds the results of sweep {old_name!r} "
            f"({old_file}), not of {name!r}. Sweep into another folder (--out DIR), or remove "
            f"{out} to replace them"
        )


def check_resumable(out: Path) -> None:
    """Raise ResultsFormatError when ``out`` holds the journal of an older pmsm-hil's sweep
    (sweep.json without this format): resuming would mix its rows (a relative axis's factor under
    the field's name, the ``_max`` metrics without the standstill segments) with today's."""
    meta, journal = Path(out) / "sweep.json", Path(out) / "results.jsonl"
    if not (meta.is_file() and journal.is_file()):
        return
    try:
        fmt = json.loads(meta.read_text(encoding="utf-8")).get("format", 1)
    except (ValueError, AttributeError):
        fmt = None
    if fmt != META_FORMAT:
        raise ResultsFormatError(
            f"{meta}: format = {fmt!r}, not {META_FORMAT}: {out} holds the results of an older "
            "pmsm-hil (a relative axis's factor under the field's name, speed_error_max_rpm "
            "without the standstill segments), which a resumed sweep would mix with today's. "
            f"Sweep into a new folder, or remove {journal} to run every run again "
            f"(`pmsm-hil sweep report {out}` still reads the old table)"
        )
