"""`pmsm-hil commission -o OUT.yaml`: the firmware's commissioning sequence on a rig or the
emulator, each step reported as it ends; the result is a commissioned motor file for
`pmsm-hil run PROFILE --motor OUT.yaml` (docs/commissioning.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Literal, TextIO

from pmsm_hil.cli.errors import fail, report
from pmsm_hil.files import write_text_whole
from pmsm_hil.seeds import seed_arg

if TYPE_CHECKING:
    from pmsm_hil.recorder import LiveState


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "commission",
        help="commission a drive: sensor offsets, encoder offset, inverter, R, L, psi_f "
        "-> a motor file",
        description="Runs the firmware's commissioning sequence (on the emulator unless "
        "--port/--can), reports each step live, logs to MCAP and writes the commissioned "
        "motor file (nominal file + measured values + calibrations, each with its spread).",
    )
    p.add_argument("-o", "--out", required=True, help="commissioned motor file to write (YAML)")
    p.add_argument(
        "--motor", default=None, help="nominal motor file or shipped name (default: paper-a-ipmsm)"
    )
    p.add_argument("--rig", default=None, help="rig file (or shipped name) for the emulator")
    p.add_argument("--port", default=None, help="serial port of a rig, e.g. /dev/ttyUSB0")
    p.add_argument(
        "--can",
        nargs="?",
        const="emulator",
        default=None,
        metavar="SPEC",
        help="use CAN (a python-can SPEC, or bare for the emulator on CAN; docs/can.md)",
    )
    p.add_argument("--baud", type=int, default=None, help="serial bit rate")
    p.add_argument("--seed", type=seed_arg, default=1, help="emulator noise seed (default 1)")
    p.add_argument(
        "--log",
        default=None,
        help="MCAP log, *.mcap (default runs/commission-DATE.mcap, -2, -3 ... when that exists); "
        "an existing one is kept unless --overwrite",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the log at --log (and with --flux-map its LOG-flux-map.mcap) if there is one",
    )
    p.add_argument(
        "--steps",
        default=None,
        help="comma-separated subset of offsets,v_dc,encoder,inverter,r_s,l_dq,psi_f "
        "(default: all); r_s and psi_f need inverter (its measured distortion); without encoder "
        "the motor file's enc_offset_e_rad is taken as the rotor angle",
    )
    p.add_argument(
        "--i-test",
        type=float,
        default=None,
        help="test current, A, in (0, the motor's i_max_a] (default i_max_a/2)",
    )
    p.add_argument(
        "--spin-rpm",
        type=float,
        default=None,
        help="psi_f spin speed, r/min, in (0, the motor's speed_max_rpm] (default "
        "speed_max_rpm/2; to skip the spin leave psi_f out of --steps)",
    )
    p.add_argument(
        "--flux-map",
        action="store_true",
        help="then measure a flux map (psi_d, psi_q vs i_d, i_q) under load, written beside the "
        "motor file and named in it",
    )
    p.add_argument(
        "--map-rpm",
        default=None,
        metavar="N1,N2",
        help="the flux map's two speeds, r/min, e.g. --map-rpm=-750,750 (default: -/+ half the "
        "motor's speed limit)",
    )
    p.add_argument("--in-process", action="store_true", help=argparse.SUPPRESS)


# the command's option for each field of the commissioning request (RequestError.field)
OPTIONS = {"steps": "--steps", "i_test_a": "--i-test", "spin_rpm": "--spin-rpm"}


class StepPrinter:
    """Prints each step as it begins and its result as it arrives (the runner's observer)."""

    def __init__(self, stream: TextIO | None = None):
        self.stream = stream or sys.stdout
        self.n_events = 0
        self.n_rows = 0

    def __enter__(self) -> StepPrinter:
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        return False

    def message(self, text: str) -> None:
        print(text, file=self.stream, flush=True)

    def update(self, live: LiveState) -> None:
        from pmsm_hil.commission.steps import STEP_TITLES, step_quantities

        lines: list[
            tuple[float, int, str]
        ] = []  # (t_s, order, text): a step's results before the next step's start
        for t_s, kind, _arg, text in live.events[self.n_events :]:
            if kind in ("commission_step", "commission_failed", "fault", "stopped"):
                step = text.split(": ", 1)[-1]
                label = STEP_TITLES.get(step, text) if kind == "commission_step" else text
                lines.append((t_s, 1, f"{t_s:7.2f} s  {label}"))
        self.n_events = len(live.events)
        for t_s, row in live.commission[self.n_rows :]:
            if row["status"] == "ok":
                for name, m in step_quantities(row).items():
                    lines.append((t_s, 0, f"            {name:<26} {m.text()}"))
        self.n_rows = len(live.commission)
        for _t, _o, text in sorted(lines, key=lambda x: (x[0], x[1])):
            print(text, file=self.stream, flush=True)


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.cli.paths import check_output
    from pmsm_hil.cli.run import default_log_path
    from pmsm_hil.commission.motor_file import commissioned_motor_yaml
    from pmsm_hil.commission.sequence import (
        RequestError,
        angle_warning,
        commission_profile,
        commission_request,
        run_commission,
    )
    from pmsm_hil.commission.steps import r_knee_warning
    from pmsm_hil.device import DeviceSpec, link_options_problem, open_device
    from pmsm_hil.errors import TransportError, TransportSpecError
    from pmsm_hil.profiles import ProfileError
    from pmsm_hil.profiles.shipped import resolve
    from pmsm_hil.protocol.session import DeviceError, Session
    from pmsm_hil.runner import HostError, PlantMismatch, RunOptions

    problem = link_options_problem(args.port, args.can, args.baud)
    if problem:
        return fail("error", problem, 2)
    out = Path(args.out)
    map_rpm = None
    if args.map_rpm is not None:
        if not args.flux_map:
            return fail("error", "--map-rpm: only with --flux-map", 2)
        try:
            map_rpm = [float(x) for x in args.map_rpm.split(",")]
        except ValueError:
            return fail(
                "error", f"--map-rpm {args.map_rpm!r}: give two speeds, e.g. --map-rpm=-750,750", 2
            )
    code = check_output(out, "-o", (".yaml", ".yml"), "the result is a motor file")
    if code is None and args.log:
        code = _kept_log(Path(args.log), args.flux_map, args.overwrite)
    if code is None and args.log:
        code = check_output(Path(args.log), "--log", (".mcap",), "the log is MCAP")
    if code is not None:
        return code
    try:
        rig = resolve(args.rig, "rig") if args.rig else None
        motor = resolve(args.motor, "motor") if args.motor else None
        profile = commission_profile(motor, rig)
    except ProfileError as e:
        return fail("error", str(e), 2)
    if args.flux_map:  # refuse a bad map request before the motor turns
        from pmsm_hil.commission.flux_map import plan_for

        try:
            plan_for(profile.motor, map_rpm)
        except ValueError as e:
            return fail("error", f"--map-rpm: {e}", 2)
    steps = [s.strip() for s in args.steps.split(",")] if args.steps else None
    try:  # what the firmware would refuse (or could not run), before the motor is energised
        commission_request(profile, steps, args.i_test, args.spin_rpm)
    except RequestError as e:
        option = OPTIONS[e.field]
        given = getattr(args, option[2:].replace("-", "_"))
        shown = f"{given:g}" if isinstance(given, float) else given
        return fail("error", f"{option} {shown}: {e}", 2)
    for w in profile.warnings:  # the motor file's plausibility, before the motor is energised
        report("warning", w)
    warning = angle_warning(profile, steps)
    if warning:
        report("warning", warning)
    if args.log:
        log, made = Path(args.log), False
    else:
        try:  # made here, exclusively: two commissionings in one second get -2, -3 ...
            log, made = default_log_path("commission"), True
        except OSError as e:
            return fail("error", f"runs/: cannot write the log there ({e.strerror or e})", 2)
    spec = DeviceSpec(
        port=args.port,
        can=args.can,
        baud=args.baud,
        rig_path=rig,
        seed=args.seed,
        in_process=args.in_process,
    )
    try:
        link = open_device(spec, profile)
    except TransportError as e:
        if made:
            log.unlink(missing_ok=True)
        return fail("error", str(e), 2 if isinstance(e, TransportSpecError) else 3)
    device = link.name if spec.is_rig else f"emulator, rig {profile.rig.name}, seed {args.seed}"
    print(f"commissioning {profile.motor.name} on {device}", flush=True)
    try:
        with StepPrinter() as printer:
            res = run_commission(
                profile,
                Session(link),
                log,
                RunOptions(
                    seed=None if spec.is_rig else args.seed,
                    rig_name=rig or "",
                    log_sync="batch" if spec.is_rig else "wall",
                ),
                printer,
                steps=steps,
                i_test_a=args.i_test,
                spin_rpm=args.spin_rpm,
            )
    except ValueError as e:
        return fail("error", str(e), 2)
    except PlantMismatch as e:
        return fail("error", f"{e} (log: {log})", 2)
    except (DeviceError, TransportError) as e:
        return fail("error", str(e), 3)
    except HostError as e:
        return fail("error", f"{e} (log: {log})", 3)
    finally:
        link.close()
    printer.update(res.run.live)  # what arrived after the last live update
    print(f"log: {log}")
    if res.run.interrupted:
        report("stopped", f"commissioning interrupted; the motor was stopped (log: {log})")
        return 130
    if res.failure:
        return fail("failed", f"{res.failure}; the motor was switched off (log: {log})", 4)
    if not res.ok:
        why = res.run.error or res.run.stop_reason or "the sequence did not complete"
        return fail("failed", f"commissioning did not complete: {why} (log: {log})", 4)
    warning = r_knee_warning(res.rows, res.quantities)
    if warning:
        report("warning", warning)
    text = commissioned_motor_yaml(
        profile.motor,
        res.quantities,
        profile.control.ts_s,
        device,
        str(log),
        out_dir=str(out.parent),
    )
    replaced = out.is_file()  # said, not refused: the README commissions into one file twice
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_text_whole(out, text)
    except OSError as e:  # writable when checked above; something changed meanwhile
        return fail("error", f"-o {out}: cannot write ({e.strerror or e}); the results: {log}", 3)
    if args.flux_map:
        from pmsm_hil.cli.commission_map import measure_map

        code = measure_map(out, profile, spec, log, device, map_rpm)
        if code:  # the commissioning's own file stays usable: say where it is
            print(
                f"motor file: {out}, without a flux map (use: pmsm-hil run PROFILE --motor {out})"
            )
            return code
    print(
        f"motor file: {out}  (use: pmsm-hil run PROFILE --motor {out})"
        + ("; it replaced the file that was there" if replaced else "")
    )
    return 0


def _kept_log(log: Path, flux_map: bool, overwrite: bool) -> int | None:
    """A log that is there already is kept, as `run --out` keeps one: the error, or None."""
    logs = [log, log.with_name(log.stem + "-flux-map.mcap")] if flux_map else [log]
    for path in logs if log.suffix == ".mcap" and not overwrite else ():
        if path.exists():
            what = (
                "a log is there already" if path == log else f"the flux map's log {path} is there"
            )
            return fail(
                "error", f"--log {log}: {what}; --overwrite replaces it (or give another name)", 2
            )
    return None
