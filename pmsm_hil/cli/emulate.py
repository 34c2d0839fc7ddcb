"""`pmsm-hil emulate`: serve the emulated F28335 (firmware core + sim board) on a pty or CAN."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from pmsm_hil.emulator.entry import add_arguments

    p = sub.add_parser(
        "emulate",
        help="serve the emulated drive on a pseudo-terminal (or CAN)",
        description="Runs the firmware core on the emulated board and serves it on "
        "a pty; prints `serial: /dev/pts/N` (or `can: SPEC` with --can) "
        "and serves until stopped.",
    )
    add_arguments(p)


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.emulator.entry import serve

    return serve(args)
