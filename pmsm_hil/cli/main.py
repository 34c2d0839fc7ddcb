"""pmsm-hil command line: one module per subcommand, each thin over the library."""
from __future__ import annotations

import argparse
import sys

from pmsm_hil import __version__
from pmsm_hil.cli import analyze, bench, emulate, gap, import_csv, run

COMMANDS = {"run": run, "emulate": emulate, "analyze": analyze, "bench": bench,
            "import": import_csv, "gap": gap}

EXIT_USER_ERROR = 2    # bad input: profile, file, option
EXIT_DEVICE_ERROR = 3  # link or device: no answer, mismatch, dropped link, fault


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pmsm-hil",
        description="Hardware-in-the-loop tool for PMSM drives: runs speed/load profiles on an "
                    "F28335 rig or its emulator, logs to MCAP, analyses logs.")
    p.add_argument("--version", action="version", version=f"pmsm-hil {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, mod in COMMANDS.items():
        mod.add_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return COMMANDS[args.command].main(args)


if __name__ == "__main__":
    sys.exit(main())
