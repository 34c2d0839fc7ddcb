"""`pmsm-hil report LOG.mcap [-o DIR]`: PNG plots and one self-contained HTML page of a run."""

from __future__ import annotations

import argparse

from pmsm_hil.cli.errors import fail


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "report",
        help="plot a run log: PNGs and one HTML page with the summary tables",
        description="Writes speed, currents, voltages, parameters vs truth, estimation "
        "error and capture plots (PNG) and report.html (self-contained) "
        "for an MCAP log written by `pmsm-hil run` (docs/report.md).",
    )
    p.add_argument("log", help="MCAP log written by `pmsm-hil run`")
    p.add_argument(
        "-o",
        "--out",
        default=None,
        metavar="DIR",
        help="directory to write into (default: LOG's name + '-report', beside the log)",
    )


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.analysis.report import ReportError, build_report

    try:
        rep = build_report(args.log, args.out)
    except ReportError as e:
        return fail("error", str(e), 2)
    for key, path in rep.pngs.items():
        print(f"{key:17s} {path}")
    for key, why in rep.skipped.items():
        print(f"{key:17s} skipped: {why}")
    print(f"{'report':17s} {rep.html}")
    return 0
