"""`pmsm-hil run PROFILE`: play a speed/load profile on a rig or the emulator, live, to MCAP."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from pmsm_hil.cli.errors import fail, report


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run a speed/load profile (on the emulator unless --port)",
                       description="Downloads PROFILE to the device, runs it, shows a live view and "
                                   "logs everything to MCAP. Without --port the emulator is started.")
    p.add_argument("profile", help="profile YAML, e.g. profiles/paper-a.yaml")
    p.add_argument("--out", "-o", default=None,
                   help="MCAP log to write (default: runs/PROFILE-YYYYmmdd-HHMMSS.mcap)")
    p.add_argument("--port", default=None, help="serial port of a rig, e.g. /dev/ttyUSB0")
    p.add_argument("--can", nargs="?", const="emulator", default=None, metavar="SPEC",
                   help="use CAN: a python-can SPEC such as socketcand:emu0@127.0.0.1:29536, "
                        "socketcan:can0, pcan:PCAN_USBBUS1 (options ,bitrate=N,node=N); "
                        "bare --can or `emulator` starts the emulator on CAN (README, docs/can.md)")
    p.add_argument("--baud", type=int, default=None, help="serial bit rate (default: the profile's)")
    p.add_argument("--rig", default=None, help="rig file for the emulator (default: the profile's)")
    p.add_argument("--seed", type=int, default=1, help="emulator noise seed (default 1)")
    p.add_argument("--no-live", action="store_true", help="plain progress lines instead of the live view")
    p.add_argument("--foxglove", nargs="?", type=int, const=8765, default=None, metavar="PORT",
                   help="also serve the live streams to Foxglove on ws://127.0.0.1:PORT "
                        "(default 8765; docs/foxglove.md)")
    p.add_argument("--stop-after", type=float, default=None, metavar="S",
                   help="ask the device to stop after S seconds of device time")


def default_log_path(profile_path: str) -> Path:
    stem = Path(profile_path).stem
    return Path("runs") / f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}.mcap"


def open_transport(args, profile):
    from pmsm_hil.transport.emulator import EmulatorTransport
    from pmsm_hil.transport.serial_port import SerialTransport

    if getattr(args, "can", None) is not None:   # docs/can.md
        from pmsm_hil.transport.can_bus import open_for_run
        rig_path = args.rig or (str(profile.rig.path) if getattr(profile.rig, "path", None) else None)
        return open_for_run(args.can, profile, rig_path, args.seed)
    baud = args.baud or profile.link.baud
    if args.port:
        return SerialTransport(args.port, baud)
    rig_path = args.rig or (str(profile.rig.path) if getattr(profile.rig, "path", None) else None)
    return EmulatorTransport(str(profile.motor.path), rig_path, args.seed, baud)


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.analysis.summary import print_summary, summarize_log
    from pmsm_hil.cli.live import make_observer
    from pmsm_hil.profiles import ProfileError, load_profile
    from pmsm_hil.protocol.session import DeviceError, Session
    from pmsm_hil.runner import RunOptions, run_profile
    from pmsm_hil.transport.base import TransportError

    try:
        profile = load_profile(args.profile, rig_override=args.rig)
    except ProfileError as e:
        return fail("error", str(e), 2)
    except FileNotFoundError as e:
        return fail("error", f"{e.filename}: no such file", 2)
    if args.baud is not None and args.baud <= 0:
        return fail("error", f"--baud {args.baud}: must be a positive bit rate", 2)
    out = Path(args.out) if args.out else default_log_path(args.profile)
    if out.suffix != ".mcap":
        return fail("error", f"--out {out}: the log is MCAP, name it *.mcap", 2)
    out.parent.mkdir(parents=True, exist_ok=True)

    sinks = []
    if args.foxglove is not None:   # docs/foxglove.md
        from pmsm_hil.live.foxglove import FoxgloveError, FoxgloveSink
        try:
            sinks.append(FoxgloveSink(args.foxglove))
        except FoxgloveError as e:
            return fail("error", str(e), 2)
        print(f"foxglove: {sinks[0].url} (layout: docs/foxglove-layout.json)", flush=True)
    try:
        transport = open_transport(args, profile)
    except TransportError as e:
        for s in sinks:
            s.close()
        return fail("error", str(e), 3)
    names = [s.name or f"segment {i}" for i, s in enumerate(profile.segments)]
    observer = make_observer(args.no_live, f"{profile.name} on {transport.name}", transport.bit_rate, names)
    rig_name = args.rig or str(getattr(profile.rig, "path", "") or "")
    is_rig = args.port or (args.can is not None and not args.can.startswith("emulator"))
    options = RunOptions(seed=None if is_rig else args.seed, rig_name=rig_name,
                         stop_after_s=args.stop_after, sinks=sinks)
    try:
        with observer:
            result = run_profile(profile, Session(transport), out, options, observer)
    except (DeviceError, TransportError) as e:
        return fail("error", str(e), 3)
    finally:
        transport.close()
        for s in sinks:
            s.close()

    print(f"log: {result.log_path}")
    try:
        summary = summarize_log(result.log_path)
        print_summary(summary)
    except Exception as e:  # the log is written; a summary problem must not hide it
        report("warning", f"could not summarise {result.log_path}: {e}")
    if result.error:
        return fail("error", f"{result.error} (log kept: {result.log_path})", 3)
    if result.interrupted:
        report("stopped", f"run interrupted; the motor was stopped and the log is complete up to "
                          f"there: {result.log_path}")
        return 130
    if result.faults:
        from pmsm_hil.recorder import fault_text
        return fail("fault", f"device faulted ({fault_text(result.faults)}); see {result.log_path}", 4)
    if result.stop_reason and result.stop_reason not in ("profile end", "host stop"):
        return fail("stopped", f"device stopped: {result.stop_reason}", 4)
    return 0
