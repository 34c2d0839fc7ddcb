"""`pmsm-hil emulate`: serve the emulated F28335 (firmware core + sim board) on a pty."""
from __future__ import annotations

import argparse

from pmsm_hil.cli.errors import fail


def add_parser(sub) -> None:
    p = sub.add_parser("emulate", help="serve the emulated drive on a pseudo-terminal",
                       description="Runs the firmware core on the emulated board and serves it on "
                                   "a pty; prints `serial: /dev/pts/N` and serves until stopped.")
    p.add_argument("--motor", default=None,
                   help="motor file of the emulated plant (default: the paper A IPMSM)")
    p.add_argument("--rig", default=None, help="rig file: the plant's departures from the model")
    p.add_argument("--seed", type=int, default=1, help="seed of the plant's noise (default 1)")
    p.add_argument("--baud", type=int, default=921600, help="emulated UART bit rate")
    p.add_argument("--can", action="store_true",
                   help="serve CAN (socketcand protocol on 127.0.0.1) instead of a pty; prints `can: SPEC`")
    p.add_argument("--can-port", type=int, default=0, help="TCP port of the CAN endpoint (default: any free)")
    p.add_argument("--can-bitrate", type=int, default=1_000_000, help="emulated CAN bit rate (default 1 Mbit/s)")
    p.add_argument("--node", type=int, default=1, help="CAN node ID of the emulated drive, 0..15 (default 1)")
    p.add_argument("--corrupt-ppm", type=float, default=0.0, metavar="PPM",
                   help="flip bits in this many of a million octets sent (tests the host's framing)")


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.emulator.server import serve_pty
    from pmsm_hil.emulator.settings import emulator_settings
    from pmsm_hil.profiles import ProfileError, load_motor, load_rig

    try:
        motor = load_motor(args.motor)
        rig = load_rig(args.rig)
    except ProfileError as e:
        return fail("error", str(e), 2)
    if args.baud <= 0:
        return fail("error", f"--baud {args.baud}: must be a positive bit rate", 2)
    settings = emulator_settings(motor, rig, seed=args.seed, baud=args.baud)
    if args.can:   # docs/can.md
        if not 10_000 <= args.can_bitrate <= 1_000_000 or not 0 <= args.node <= 15:
            return fail("error", "--can-bitrate must be 10000..1000000 and --node 0..15", 2)
        from pmsm_hil.emulator.socketcand_server import serve_socketcand
        settings.update(can_bitrate=float(args.can_bitrate), can_node=float(args.node))
        serve_socketcand(settings, announce=lambda s: print(s, flush=True), port=args.can_port)
        return 0
    serve_pty(settings, announce=lambda s: print(s, flush=True), corrupt_ppm=args.corrupt_ppm)
    return 0
