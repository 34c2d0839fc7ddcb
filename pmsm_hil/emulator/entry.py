"""The emulator's own entry point: `python -P -m pmsm_hil.emulator` (what the host starts as its
child) and `pmsm-hil emulate` (the same options, for a user who serves it by hand).

It does not boot through the CLI: it reads the motor and rig files, builds the sim board's
settings and serves a pty (or a CAN endpoint) until SIGTERM/SIGINT. The host passes the settings
it has already built (``--settings-file``, JSON), so its child reads no file and imports neither the
profile loader nor pydantic: its start is on the critical path of every `pmsm-hil run`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from pmsm_hil.seeds import seed_arg

EXIT_USER_ERROR = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--motor",
        default=None,
        help="motor file of the emulated plant, a path or a shipped name "
        "(default: the profile's, else paper-a-ipmsm)",
    )
    p.add_argument(
        "--rig",
        default=None,
        help="rig file: the plant's departures from the model, a path or a shipped name "
        "(default: the profile's, else default)",
    )
    p.add_argument(
        "--profile",
        default=None,
        help="take the motor and rig from this profile (a path or a shipped name)",
    )
    p.add_argument("--seed", type=seed_arg, default=1, help="seed of the plant's noise (default 1)")
    p.add_argument(
        "--truth-hz",
        type=float,
        default=None,
        metavar="HZ",
        help="sim_truth frames per second of device time (default: the profile's "
        "telemetry.truth_hz, else 100; 0: none)",
    )
    p.add_argument("--baud", type=int, default=921600, help="emulated UART bit rate")
    p.add_argument(
        "--pace",
        type=float,
        default=None,
        metavar="X",
        help="run at X times real time (1 = real time; default: as fast as the host reads)",
    )
    p.add_argument(
        "--can",
        action="store_true",
        help="serve CAN (socketcand protocol on 127.0.0.1) instead of a pty; prints `can: SPEC`",
    )
    p.add_argument(
        "--can-port", type=int, default=0, help="TCP port of the CAN endpoint (default: any free)"
    )
    p.add_argument(
        "--can-bitrate",
        type=int,
        default=1_000_000,
        help="emulated CAN bit rate (default 1 Mbit/s)",
    )
    p.add_argument(
        "--node", type=int, default=1, help="CAN node ID of the emulated drive, 0..15 (default 1)"
    )
    p.add_argument(
        "--report-state",
        action="store_true",
        help="print a line each time the drive's state changes (device time, and the "
        "device time since the last heartbeat)",
    )
    p.add_argument(
        "--exit-with-parent",
        action="store_true",
        help="end once the process that started the emulator is gone and the drive is at "
        "rest (the host sets this for the emulator it starts)",
    )
    p.add_argument(
        "--settings-file",
        default=None,
        metavar="FILE",
        help='the sim board\'s settings as built by the host, JSON: {"settings": {...}, "plant": '
        '"motor: NAME  rig: NAME"} (instead of --motor/--rig/--profile)',
    )
    p.add_argument(
        "--corrupt-ppm",
        type=float,
        default=0.0,
        metavar="PPM",
        help="flip bits in this many of a million octets sent (tests the host's framing)",
    )
    p.add_argument(
        "--drop-ppm",
        type=float,
        default=0.0,
        metavar="PPM",
        help="lose this many of a million octets sent (a noisy line; docs/faults.md)",
    )
    p.add_argument(
        "--noise-h2d",
        action="store_true",
        help="apply --corrupt-ppm and --drop-ppm to the octets from the host too",
    )


def _error(message: str) -> int:
    print(f"error: {message}", file=sys.stderr, flush=True)
    return EXIT_USER_ERROR


def _motor_and_rig(args: argparse.Namespace):
    from pmsm_hil.profiles import load_motor, load_profile, load_rig
    from pmsm_hil.profiles.shipped import resolve

    if args.profile is not None:
        profile = load_profile(
            resolve(args.profile, "profile"),
            rig_override=resolve(args.rig, "rig") if args.rig else None,
        )
        motor = load_motor(resolve(args.motor, "motor")) if args.motor else profile.motor
        return motor, profile.rig, profile.telemetry.truth_hz
    motor = load_motor(resolve(args.motor, "motor") if args.motor else None)
    rig = load_rig(resolve(args.rig, "rig") if args.rig else None)
    return motor, rig, 100.0


def serve(args: argparse.Namespace) -> int:
    """Serve the emulated drive until stopped; 2 on bad options or files."""
    if args.settings_file is not None:
        try:
            with open(args.settings_file, encoding="utf-8") as f:
                given = json.load(f)
            settings = dict(given["settings"])
            plant = str(given.get("plant", ""))
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
            return _error(f"--settings-file {args.settings_file}: not the host's settings ({e})")
    else:
        from pmsm_hil.emulator.settings import emulator_settings
        from pmsm_hil.profiles import ProfileError

        try:
            motor, rig, truth_hz = _motor_and_rig(args)
        except ProfileError as e:
            return _error(str(e))
        if args.truth_hz is not None:
            if not 0 <= args.truth_hz <= 50_000:
                return _error(f"--truth-hz {args.truth_hz:g}: must be 0..50000 Hz (0: no frames)")
            truth_hz = args.truth_hz
        settings = emulator_settings(motor, rig, seed=args.seed, baud=args.baud, truth_hz=truth_hz)
        plant = f"motor: {motor.name}  rig: {rig.name or 'default'}"
    if args.baud <= 0:
        return _error(f"--baud {args.baud}: must be a positive bit rate")
    if args.pace is not None and not 0.001 <= args.pace <= 1000:
        return _error(f"--pace {args.pace}: must be between 0.001 and 1000 (times real time)")
    for flag, v in (("--corrupt-ppm", args.corrupt_ppm), ("--drop-ppm", args.drop_ppm)):
        if not 0 <= v <= 1e6:
            return _error(f"{flag} {v}: must be 0..1000000 (octets in a million)")
    parent = os.getppid() if args.exit_with_parent else None

    def announce(s):
        return print(f"{s}\n{plant}", flush=True)

    if args.can:  # docs/can.md
        if not 10_000 <= args.can_bitrate <= 1_000_000 or not 0 <= args.node <= 15:
            return _error("--can-bitrate must be 10000..1000000 and --node 0..15")
        from pmsm_hil.emulator.socketcand_server import serve_socketcand

        settings.update(can_bitrate=float(args.can_bitrate), can_node=float(args.node))
        serve_socketcand(
            settings,
            announce=announce,
            port=args.can_port,
            pace=args.pace,
            report_state=args.report_state,
            parent_pid=parent,
        )
        return 0
    from pmsm_hil.emulator.server import serve_pty

    serve_pty(
        settings,
        announce=announce,
        corrupt_ppm=args.corrupt_ppm,
        drop_ppm=args.drop_ppm,
        noise_h2d=args.noise_h2d,
        pace=args.pace,
        report_state=args.report_state,
        parent_pid=parent,
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m pmsm_hil.emulator",
        description="Serve the emulated drive (firmware core + sim board).",
    )
    add_arguments(p)
    return serve(p.parse_args(argv))
