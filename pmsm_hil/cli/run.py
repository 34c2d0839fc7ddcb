"""`pmsm-hil run PROFILE`: play a speed/load profile on a rig or the emulator, live, to MCAP."""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import os
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.cli.errors import device_ended_early, fail, report
from pmsm_hil.seeds import seed_arg

if TYPE_CHECKING:
    from pmsm_hil.device import DeviceSpec
    from pmsm_hil.profiles import Profile

# main returns with the log closed, the device's link and the emulator child (stopped and waited
# for) closed, and its threads ended: the process may end without the interpreter's teardown
# (pmsm_hil.cli.main.entry)
ENDS_CLEAN = True


def _port_arg(text: str) -> int:
    """--foxglove PORT: a whole number (its range is checked where the server opens)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a TCP port (a whole number 0..65535; 0 picks a free one)"
        ) from None


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "run",
        help="run a speed/load profile (on the emulator unless --port/--can)",
        description="Downloads PROFILE to the device, runs it, shows a live view and "
        "logs everything to MCAP. Without --port the emulator is started.",
    )
    p.add_argument(
        "profile",
        help="profile YAML, or the name of a shipped profile (`pmsm-hil profiles`), "
        "e.g. profiles/paper-a.yaml or paper-a",
    )
    p.add_argument(
        "--out",
        "-o",
        default=None,
        help="MCAP log to write (default: runs/PROFILE-YYYYmmdd-HHMMSS.mcap); an existing one is "
        "kept unless --overwrite",
    )
    p.add_argument(
        "--overwrite", action="store_true", help="replace the log at --out if there is one"
    )
    p.add_argument("--port", default=None, help="serial port of a rig, e.g. /dev/ttyUSB0")
    p.add_argument(
        "--can",
        nargs="?",
        const="emulator",
        default=None,
        metavar="SPEC",
        help="use CAN: a python-can SPEC such as socketcand:emu0@127.0.0.1:29536, "
        "socketcan:can0, pcan:PCAN_USBBUS1 (options ,bitrate=N,node=N); "
        "bare --can or `emulator` starts the emulator on CAN (README, docs/can.md)",
    )
    p.add_argument(
        "--baud", type=int, default=None, help="serial bit rate (default: the profile's)"
    )
    p.add_argument(
        "--motor",
        default=None,
        help="motor file (or shipped name) instead of the profile's, e.g. a commissioned one",
    )
    p.add_argument(
        "--rig",
        default=None,
        help="rig file (or shipped name) for the emulator (default: the profile's)",
    )
    p.add_argument("--seed", type=seed_arg, default=1, help="emulator noise seed (default 1)")
    p.add_argument(
        "--pace",
        type=float,
        default=None,
        metavar="X",
        help="run the emulator at X times real time (1 = real time) so the live view can "
        "be watched (default: as fast as possible)",
    )
    p.add_argument(
        "--decimate",
        action="store_true",
        help="when the link cannot carry the profile's telemetry, lower the fast-frame "
        "rate to what fits (default: refuse the run and show the budget)",
    )
    p.add_argument(
        "--no-live", action="store_true", help="plain progress lines instead of the live view"
    )
    p.add_argument(
        "--foxglove",
        nargs="?",
        type=_port_arg,
        const=8765,
        default=None,
        metavar="PORT",
        help="also serve the live streams to Foxglove on ws://127.0.0.1:PORT "
        "(default 8765; docs/foxglove.md)",
    )
    p.add_argument(
        "--stop-after",
        type=float,
        default=None,
        metavar="S",
        help="stop the run after S seconds of device time (the device stops itself at that "
        "control period: stop_at, docs/protocol.md)",
    )


def default_log_path(profile_path: str) -> Path:
    """runs/PROFILE-YYYYmmdd-HHMMSS.mcap, or -2, -3 ... after it when a run started in the same
    second has that name: the file is created here, exclusively, so that two runs never share a
    log (OSError when runs/ cannot be written)."""
    base = f"{Path(profile_path).stem}-{time.strftime('%Y%m%d-%H%M%S')}"
    runs = Path("runs")
    runs.mkdir(parents=True, exist_ok=True)
    k = 1
    while True:
        path = runs / (base + (f"-{k}" if k > 1 else "") + ".mcap")
        try:
            os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
        except FileExistsError:
            k += 1
            continue
        return path


def device_spec(args: argparse.Namespace) -> DeviceSpec:
    from pmsm_hil.device import DeviceSpec

    return DeviceSpec(
        port=args.port,
        can=args.can,
        baud=args.baud,
        rig_path=args.rig,
        seed=args.seed,
        pace=args.pace,
    )


def budget_text(budget: dict, baud: int) -> str:
    lines = [f"link budget at {baud} baud ({budget['capacity_octets_s']:.0f} octets/s):"]
    for name, st in budget["streams"].items():
        if st["octets_s"]:
            lines.append(
                f"  {name:<10} {st['rate_hz'] * st['count']:8.1f} frames/s x {st['frame_octets']:3d} "
                f"octets = {st['octets_s']:8.0f} octets/s ({100 * st['share']:5.1f} %)"
            )
    lines.append(
        f"  total {budget['total_octets_s']:.0f} octets/s = {100 * budget['load']:.0f} % of the link"
    )
    return "\n".join(lines)


def check_link_budget(args: argparse.Namespace, profile: Profile) -> int | None:
    """Serial links: refuse telemetry that the link cannot carry, or decimate it (--decimate)."""
    from pmsm_hil.profiles import link_budget

    if args.can is not None:
        return None  # CAN rates are fitted to the bus in open_for_run (docs/can.md)
    baud = args.baud or profile.link.baud
    profile.link = profile.link.model_copy(update={"baud": baud})
    budget = link_budget(profile, emulator=not args.port)
    if budget["load"] <= 1.0:
        return None
    if not args.decimate or budget["fast_hz_fit"] <= 0:
        why = (
            "no fast-frame rate fits beside the other streams; lower telemetry.params_hz/status_hz "
            "or raise the bit rate"
            if budget["fast_hz_fit"] <= 0
            else f"lower telemetry.fast_hz to {budget['fast_hz_fit']:g} Hz, raise --baud, or pass "
            f"--decimate to run at {budget['fast_hz_fit']:g} Hz"
        )
        return fail(
            "error",
            f"{profile.path}: the link cannot carry this telemetry; {why}\n"
            f"{budget_text(budget, baud)}",
            2,
        )
    old = profile.telemetry.fast_hz
    profile.telemetry = profile.telemetry.model_copy(update={"fast_hz": budget["fast_hz_fit"]})
    report(
        "note",
        f"telemetry.fast_hz decimated from {old:g} Hz to {budget['fast_hz_fit']:g} Hz to fit "
        f"{baud} baud (--decimate)",
    )
    return None


def _check_out(out: Path, overwrite: bool = False) -> int | None:
    from pmsm_hil.cli.paths import check_output

    if out.is_dir():
        return fail("error", f"--out {out}: is a directory; give the log's file name (*.mcap)", 2)
    if out.exists() and not overwrite and out.suffix == ".mcap":
        return fail(
            "error",
            f"--out {out}: a log is there already; --overwrite replaces it (or give another name)",
            2,
        )
    return check_output(out, "--out", (".mcap",), "the log is MCAP")


def _load(args):
    from pmsm_hil.profiles import load_profile
    from pmsm_hil.profiles.shipped import resolve

    path = resolve(args.profile, "profile")
    rig = resolve(args.rig, "rig") if args.rig else None
    motor = resolve(args.motor, "motor") if args.motor else None
    args.rig = rig
    return load_profile(path, rig_override=rig, motor_override=motor)


# what the run needs after the device is open: imported while the emulator child starts
_LATER = (
    "pmsm_hil.runner",
    "pmsm_hil.cli.live",
    "pmsm_hil.analysis.summary",
    "pmsm_hil.analysis.summary_text",
    "pmsm_hil.analysis.reading",
    "pmsm_hil.analysis.acceptance",
    "pmsm_hil.cli.analyze",
    "rich.console",  # the summary's
    "rich.table",
    "rich.box",
    "rich.measure",
)
# what opening the device imports (before the thread above starts, so that the two import
# disjoint modules)
_DEVICE = (
    "pmsm_hil.transport.emulator",
    "pmsm_hil.transport.serial_port",
    "pmsm_hil.emulator.settings",
)


def _import_meanwhile(names: tuple[str, ...]) -> threading.Thread:
    """Imports ``names`` in a thread while the main thread waits on the emulator child's start
    (it waits in select, the child runs on another core): the run's start does not wait for
    both. A module that fails to import here is imported again, and reported, where it is used."""

    def load() -> None:
        for name in names:
            with contextlib.suppress(Exception):
                importlib.import_module(name)

    t = threading.Thread(target=load, name="pmsm-hil imports", daemon=True)
    t.start()
    return t


def main(args: argparse.Namespace) -> int:
    """`pmsm-hil run`. The garbage collector is held off while the run starts (see ``_settle``)."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        return _run(args, collecting)
    finally:
        gc.unfreeze()  # an in-process caller gets its collector back as it was
        if collecting:
            gc.enable()


def _settle(collecting: bool) -> None:
    """The imports and the profile's validation are done: the objects they made (some 10^5:
    pydantic's schemas, numpy's tables, the modules), made without the collector's passes, are
    moved out of its reach, and collection resumes: the stream's collections walk the stream's
    own objects only. paper-a's run spent 53 ms in 141 collections, most of them during the start."""
    gc.freeze()
    if collecting:
        gc.enable()


def _run(args: argparse.Namespace, collecting: bool) -> int:
    from pmsm_hil.device import link_options_problem, open_device
    from pmsm_hil.errors import TransportError, TransportSpecError
    from pmsm_hil.profiles import ProfileError

    problem = link_options_problem(args.port, args.can, args.baud)
    if problem:
        return fail("error", problem, 2)
    try:
        profile = _load(args)
    except ProfileError as e:
        return fail("error", str(e), 2)
    if args.baud is not None and args.baud <= 0:
        return fail("error", f"--baud {args.baud}: must be a positive bit rate", 2)
    if args.pace is not None and not 0.001 <= args.pace <= 1000:
        return fail(
            "error", f"--pace {args.pace}: must be between 0.001 and 1000 (times real time)", 2
        )
    if args.stop_after is not None and not args.stop_after > 0:
        return fail(
            "error", f"--stop-after {args.stop_after}: must be a positive device time (s)", 2
        )
    emulator = not args.port and args.can in (None, "emulator", "")
    if args.pace is not None and not emulator:
        return fail("error", "--pace sets the emulator's speed; a rig runs in real time", 2)
    if args.foxglove is not None and args.pace is None and emulator:
        args.pace = 1.0  # a stream to watch: not over before Foxglove has connected
        report("note", "--foxglove: the emulator runs in real time (--pace 1; --pace N for N x)")
    for w in profile.warnings:
        report("warning", w)
    if emulator:
        from pmsm_hil.commission.motor_file import other_rig_warning

        w = other_rig_warning(profile.motor, profile.rig.name)
        if w:
            report("warning", w)
    code = check_link_budget(args, profile)
    if code is not None:
        return code
    if args.out:
        out = Path(args.out)
        existed = out.exists()
        code = _check_out(out, args.overwrite)
        if code is not None:
            return code
    else:
        try:
            out = default_log_path(args.profile)
        except OSError as e:
            return fail("error", f"runs/: cannot write the log there ({e.strerror or e})", 2)
        existed = False  # made for this run: removed again if the device cannot be opened

    sinks = []
    if args.foxglove is not None:  # docs/foxglove.md
        from pmsm_hil.live.foxglove import FoxgloveError, FoxgloveSink, layout_path

        try:
            sinks.append(FoxgloveSink(args.foxglove))
        except FoxgloveError as e:
            if not existed:  # the log made for this run: nothing was run
                out.unlink(missing_ok=True)
            return fail("error", str(e), 2)
        print(f"foxglove: {sinks[0].url} (layout: {layout_path()})", flush=True)
    for name in _DEVICE:
        importlib.import_module(name)
    later = _import_meanwhile(_LATER)
    fast_hz = profile.telemetry.fast_hz
    try:
        dev = device_spec(args)
        link = open_device(dev, profile)
    except TransportError as e:
        for s in sinks:
            s.close()
        if not existed:
            out.unlink(missing_ok=True)
        return fail("error", str(e), 2 if isinstance(e, TransportSpecError) else 3)
    if profile.telemetry.fast_hz < fast_hz:  # over CAN: fitted to the bus (device.apply_can_rates)
        report(
            "note",
            f"telemetry.fast_hz {profile.telemetry.fast_hz:g} Hz over CAN at "
            f"{profile.link.can.bitrate / 1e3:g} kbit/s, not the profile's {fast_hz:g} Hz: what "
            "fits 95 % of the bus beside the other streams (link.can.fast_hz sets it; docs/can.md)",
        )
    try:  # a Ctrl-C (or SIGTERM) before the stream: the device closed (the emulator ended)
        later.join()
        from pmsm_hil.analysis.summary import summarize_log
        from pmsm_hil.analysis.summary_text import print_summary
        from pmsm_hil.cli.live import make_observer
        from pmsm_hil.log.writer import LogWriteError
        from pmsm_hil.protocol.session import DeviceError, Session
        from pmsm_hil.runner import (
            HEARTBEAT_WALL_S,
            HostError,
            PlantMismatch,
            RunOptions,
            run_profile,
        )

        _settle(collecting)

        names = [s.name or f"segment {i}" for i, s in enumerate(profile.segments)]
        observer = make_observer(
            args.no_live, f"{profile.name} on {link.name}", link.bit_rate, names
        )
        options = RunOptions(
            seed=None if dev.is_rig else args.seed,
            rig_name=args.rig or str(profile.rig.path or ""),
            stop_after_s=args.stop_after,
            sinks=sinks,
            # every received message on disk (the log's journal) before the next read: a killed
            # host loses nothing it received (docs/faults.md)
            log_sync="batch",
            # an emulator paced at X times real time waits 1/X of the heartbeat timeout of wall time
            heartbeat_wall_s=min(
                HEARTBEAT_WALL_S, profile.control.heartbeat_timeout_s / (4 * (args.pace or 1))
            ),
        )
    except BaseException:
        link.close()
        for s in sinks:
            s.close()
        raise
    try:
        with observer:
            result = run_profile(profile, Session(link), out, options, observer)
    except PlantMismatch as e:
        return fail("error", f"{e} (the run was aborted; log: {out})", 2)
    except (DeviceError, TransportError) as e:
        return fail("error", str(e), 3)
    except HostError as e:
        return fail("error", f"{e} (log: {out})", 3)
    except LogWriteError as e:  # the end of the run (capture, summary) could not be written
        return fail(
            "error",
            f"{e.strerror}; the run had ended (the motor was stopped); recover the log with "
            f"`pmsm-hil log recover {out}`",
            3,
        )
    finally:
        link.close()
        for s in sinks:
            s.close()
    return _finish(result, print_summary, summarize_log, profile, args.stop_after)


def _finish(result, print_summary, summarize_log, profile=None, stop_after_s=None) -> int:
    try:
        print(f"log: {result.log_path}")
        from pmsm_hil.analysis.reading import read_for_analysis
        from pmsm_hil.cli.analyze import identification, print_identification

        log = read_for_analysis(result.log_path)
        summary = summarize_log(result.log_path, log)
        print_summary(summary, interrupted=result.interrupted, error=bool(result.error))
        ident = identification(result.log_path, log)
        if ident is not None:
            print_identification(ident)
        if stop_after_s is not None and not summary.complete and not result.error:
            print(
                f"stopped after {stop_after_s:g} s of device time, as --stop-after asked: the "
                "rest of the profile was not played (exit 0; `analyze` judges the log as "
                "incomplete, exit 1)"
            )
        if profile is not None and summary.complete:
            from pmsm_hil.analysis.acceptance import acceptance_line, hints, profile_checks
            from pmsm_hil.profiles.current_step import current_step

            checks = profile_checks(profile, result.log_path, summary, log)
            if checks:
                print(acceptance_line(checks))
                for hint in hints(
                    checks, profile.motor.yaml_text, profile.rig.yaml_text, current_step(profile)
                ):
                    print(f"hint: {hint}")
    except (
        BrokenPipeError
    ):  # `| head`: the reader left; the exit code still tells how the run ended
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (
        OSError,
        ValueError,
        KeyError,
    ) as e:  # the log is written; a summary problem must not hide it
        report("warning", f"could not summarise {result.log_path}: {e}")
    if result.error:
        return fail("error", f"{result.error} (log kept: {result.log_path})", 3)
    if result.interrupted:
        report(
            "stopped",
            f"run interrupted; the motor was stopped and the log is complete up to "
            f"there: {result.log_path}",
        )
        return 130
    code = device_ended_early(result, profile, f"see {result.log_path}")
    return 0 if code is None else code
