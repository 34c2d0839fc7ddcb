"""`pmsm-hil import FILE.csv --motor M.yaml -o OUT.mcap`: external data for the gap diagnosis."""

from __future__ import annotations

import argparse

from pmsm_hil.cli.errors import fail


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "import", help="import control-rate or steady-state dq data from a CSV (docs/gap.md)"
    )
    p.add_argument("csv", help="CSV file: a header row, SI units, the project's column names")
    p.add_argument(
        "--motor",
        required=True,
        help="motor file the data belongs to (a path, or a shipped motor by its name)",
    )
    p.add_argument("-o", "--out", required=True, help="MCAP log to write")


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.gap.csv_import import ImportError_, import_csv
    from pmsm_hil.profiles import ProfileError

    try:
        from pmsm_hil.profiles.shipped import resolve

        s = import_csv(args.csv, resolve(args.motor, "motor"), args.out)
    except (ImportError_, ProfileError) as e:
        return fail("error", str(e), 2)
    ts = f", sample time {s['ts_s']:.6g} s" if s["ts_s"] else ""
    print(f"{args.out}: {s['rows']} rows of {s['kind']} data{ts} ({s['topic']})")
    return 0
