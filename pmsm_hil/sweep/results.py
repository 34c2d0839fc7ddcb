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

__all__ = ["FIRST_COLUMNS", "LAST_COLUMNS", "Journal", "read_table", "write_table"]

FIRST_COLUMNS = ("index", "key", "status", "seed")
LAST_COLUMNS = ("state", "stop_reason", "log_path", "error", "acceptance_checks", "wall_s")


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
            f.write(json.dumps(row, sort_keys=True) + "\n")
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
