"""`pmsm-hil gap`: sim-to-real gap diagnosis (docs/gap.md).

pmsm-hil gap LOG.mcap --motor M.yaml [--json] [--report DIR] [--holdout LOG2.mcap] [--workers W]
pmsm-hil gap augment LOG.mcap [--motor M.yaml] -o fitted-rig.yaml
pmsm-hil gap record PROFILE.yaml --rig RIG.yaml [--motor M.yaml] -o real.mcap [--seed N] [--overwrite]  (emulator)
pmsm-hil gap selftest --trials N --seed S [--workers W] [--scheduler ADDR] [-o DIR] [--json]
    (trials on Dask, docs/sweep.md; -o DIR keeps a journal there, so an interrupted run resumes)
pmsm-hil gap verify LOG.mcap --rig fitted-rig.yaml [--json]        (re-runs the log's profile)
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.cli.errors import device_ended_early, fail, report
from pmsm_hil.seeds import seed_arg

if TYPE_CHECKING:
    from pmsm_hil.gapgen.recorder import Recorded

ACTIONS = ("augment", "record", "selftest", "verify")


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "gap",
        help="diagnose the sim-to-real gap of a log (also: augment, record, selftest)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("target", help="LOG.mcap, or one of: " + ", ".join(ACTIONS))
    p.add_argument("rest", nargs="*", default=[], help="the log (augment) or profile (record)")
    p.add_argument(
        "--motor",
        help="motor file of the nominal model, a path or a shipped name (default: the log's "
        "motor.yaml); record: the motor instead of the profile's (as `run --motor`)",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--report", metavar="DIR", help="write plots, gap.json and index.html here")
    p.add_argument(
        "--holdout", metavar="LOG", help="a second record of the same rig: held-out closure"
    )
    p.add_argument(
        "-o",
        "--out",
        help="output file (augment: rig yaml; record: log); selftest: a folder for the "
        "trials' journal (resumable)",
    )
    p.add_argument("--overwrite", action="store_true", help="record: replace a log already at -o")
    p.add_argument("--rig", help="record, verify: the rig file (or shipped name)")
    p.add_argument("--trials", type=int, default=20, help="selftest: number of trials")
    p.add_argument(
        "--seed",
        type=seed_arg,
        default=1,
        help="selftest / record: seed; verify: the re-runs' noise seed (take one other than "
        "the record's)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="the diagnosis: processes for its fits (the same result for any number; default: one "
        "per core, at most 4); selftest: workers of the local Dask cluster (default: CPUs)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDR",
        help="selftest: a Dask scheduler, e.g. tcp://HOST:8786 (default: a local cluster)",
    )


def _record_ended(rec: Recorded, out: str) -> int:
    """Exit code of `gap record` from how its run ended, said as `run` says it: a fault or a
    stop before the profile's end leaves a record of the run up to there (it can be diagnosed,
    but it lacks the operating points after the stop)."""
    res = rec.result
    t_end = float(rec.cols["t_s"][-1]) if len(rec.cols["t_s"]) else 0.0
    kept = (
        f"the record holds the run up to {t_end:.3f} s of the profile's "
        f"{rec.profile.total_duration_s:g} s: {out}"
    )
    if res.interrupted:
        print(f"stopped: run interrupted; the motor was stopped and {kept}", file=sys.stderr)
        return 130
    code = device_ended_early(res, rec.profile, kept)
    return 0 if code is None else code


def _out_problem(path: str, what: str, overwrite: bool = True) -> str | None:
    """Why ``path`` cannot be written as the file ``what`` (None: it can)."""
    if os.path.isdir(path):
        return f"-o {path}: is a directory; give the {what} file to write (e.g. {path}/{what})"
    parent = os.path.dirname(os.path.abspath(path))
    if os.path.exists(parent) and not os.path.isdir(parent):
        return f"-o {path}: {parent} is a file, not a folder"
    if not os.path.isdir(parent):
        return f"-o {path}: its folder {parent} does not exist"
    from pmsm_hil.cli.paths import write_problem  # as `run --out`

    return write_problem(Path(path), "-o", overwrite)


def _motor(args, log_path):
    from pmsm_hil.gap.model import MotorModel
    from pmsm_hil.log.reader import read_log
    from pmsm_hil.profiles import load_motor

    if args.motor:  # a path, or a shipped motor by its name
        from pmsm_hil.profiles.shipped import resolve

        return MotorModel.from_motor(load_motor(resolve(args.motor, "motor")))
    log = read_log(log_path)
    att = [a for a in log.attachments if a.name == "motor.yaml"]
    if not att:
        cut = (
            " (the file is cut short: its attachments are in the part that is missing)"
            if log.truncated or not log.finalised
            else ""
        )
        raise ValueError(f"{log_path}: the log carries no motor.yaml{cut}; give --motor")
    with tempfile.NamedTemporaryFile("wb", suffix=".yaml", delete=False) as f:
        f.write(att[0].data)
    try:
        return MotorModel.from_motor(load_motor(f.name))
    finally:
        os.unlink(f.name)


def _reruns(log_path) -> bool:
    """Whether `gap verify` can re-run the log's profile (a `pmsm-hil run` log: its attachments)."""
    from pmsm_hil.log.reader import read_log

    names = {a.name for a in read_log(log_path, topics={}).attachments}
    return {"profile.yaml", "motor.yaml"} <= names


def _diagnose(args, path):
    from pmsm_hil.gap.diagnose import diagnose
    from pmsm_hil.gap.record import SteadyRecord, load_record
    from pmsm_hil.gap.steady import diagnose_steady

    m = _motor(args, path)
    rec = load_record(path)
    if isinstance(rec, SteadyRecord):
        return diagnose_steady(rec, m), m, rec
    hold = load_record(args.holdout) if args.holdout else None
    if isinstance(hold, SteadyRecord):
        raise ValueError(
            f"{args.holdout}: holds steady-state data; a held-out record for control-rate data "
            "must be control-rate too"
        )
    with _status(not args.json, f"gap: {path}") as say:
        res = diagnose(rec, m, holdout=hold, seed=args.seed, progress=say, workers=_workers(args))
        return res, m, rec


def _workers(args: argparse.Namespace) -> int:
    """The diagnosis's fit processes: one per core, at most 4 (each holds the record, and the
    final fit does not divide further)."""
    return int(args.workers or min(os.cpu_count() or 1, 4))


@contextlib.contextmanager
def _status(show: bool, title: str):
    """A status line on a terminal's stderr while a long diagnosis runs (what it fits, the time
    so far); nothing otherwise (a pipe, a log, --json)."""
    if not (show and sys.stderr.isatty()):
        yield lambda _msg: None
        return
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
    from rich.table import Column

    # the message takes what the line has left (cut at its end), the time keeps its width
    text = TextColumn("{task.description}", table_column=Column(ratio=1, no_wrap=True))
    clock = TimeElapsedColumn(table_column=Column(min_width=7, no_wrap=True))
    columns = (SpinnerColumn(), clock, text)
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task(title, total=None)  # the time runs on between the messages
        yield lambda msg: bar.update(task, description=f"{title}: {msg}")


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.errors import DeviceError
    from pmsm_hil.gap.record import RecordError
    from pmsm_hil.log.reader import LogFormatError, path_problem
    from pmsm_hil.profiles import ProfileError

    if args.workers is not None and args.workers < 1:
        return fail("error", f"--workers = {args.workers} must be >= 1", 2)
    if args.trials < 1:
        return fail("error", f"--trials = {args.trials} must be >= 1", 2)
    if args.report and os.path.exists(args.report) and not os.path.isdir(args.report):
        return fail("error", f"--report {args.report}: is a file; give a folder for the report", 2)
    try:
        if args.target == "selftest":
            from pmsm_hil.cli.paths import folder_problem
            from pmsm_hil.gapgen.selftest import print_selftest, run_selftest

            why = folder_problem(Path(args.out)) if args.out else None
            if why:
                return fail("error", f"-o {args.out}: {why}", 2)

            res = run_selftest(
                args.trials,
                args.seed,
                workers=args.workers,
                progress=not args.json,
                out=args.out,
                scheduler=args.scheduler,
            )
            if args.json:
                print(
                    json.dumps(
                        res, indent=1, default=lambda o: o.item() if hasattr(o, "item") else str(o)
                    )
                )
            else:
                print_selftest(res)
            return 0
        if args.target == "record":
            from pmsm_hil.gapgen.recorder import record_profile

            if not args.rest or not args.out:
                return fail("error", "gap record PROFILE.yaml [--rig RIG.yaml] -o OUT.mcap", 2)
            why = _out_problem(args.out, "record.mcap", overwrite=args.overwrite)
            if why:
                return fail("error", why, 2)
            from pmsm_hil.gap.record import foc_throughout
            from pmsm_hil.profiles import load_profile
            from pmsm_hil.profiles.shipped import resolve

            profile_path = resolve(args.rest[0], "profile")
            # --motor replaces the profile's motor file, as `run --motor` (it was ignored here)
            motor_path = resolve(args.motor, "motor") if args.motor else None
            spec = load_profile(profile_path, motor_override=motor_path).spec
            # the diagnosis would refuse its record: say so before the run
            if foc_throughout(spec.control.current_ctrl, (g.current_ctrl for g in spec.segments)):
                return fail(
                    "error",
                    f"{args.rest[0]}: current_ctrl: foc throughout (a PWM modulator): its record "
                    "could not be diagnosed, which needs the switching states of FCS-MPCC "
                    "(docs/gap.md); record an MPCC profile, e.g. the shipped `diagnose`",
                    2,
                )

            rec = record_profile(
                profile_path,
                args.out,
                rig_path=resolve(args.rig, "rig") if args.rig else None,
                seed=args.seed,
                motor_path=motor_path,
            )
            print(f"{args.out}: {len(rec.cols['t_s'])} control periods recorded")
            return _record_ended(rec, args.out)
        if args.target == "verify":
            from pmsm_hil.gapgen.verify import verify

            if not args.rest or not args.rig:
                return fail("error", "gap verify LOG.mcap --rig fitted-rig.yaml", 2)
            from pmsm_hil.profiles.shipped import resolve

            why = path_problem(args.rest[0])
            if why:
                return fail("error", why, 2)
            # a rig file, or a shipped rig by its name (`--rig lab-typical`), as for `gap record`
            v = verify(args.rest[0], resolve(args.rig, "rig"), seed=args.seed)
            if args.json:
                print(json.dumps(v))
            else:
                for tag, st in v["stopped_early"].items():
                    print(
                        f"gap verify: the {tag} rig's re-run stopped at {st['t_s']:.3f} s "
                        f"({st['why']}): its signals are compared up to there, the profile's "
                        "rest not at all"
                    )
                print(
                    f"gap verify: free-run closure (median over i_d, i_q, u_d, u_q) {v['closure_median']:.2f}"
                )
                for k, s in v["signals"].items():
                    print(
                        f"  {k:10s} rms error nominal {s['rms_nominal']:.3g}, fitted {s['rms_fitted']:.3g}, "
                        f"closure {s['closure']:.2f}"
                    )
                print(
                    "  (closure = 1 - (fitted / nominal rms error)^2; where the nominal error is "
                    "already small it swings from run to run, as the two runs' FCS switching "
                    "diverges: read the median and the settled means below)"
                )
                print(
                    "gap verify: closure of the segments' settled means (median over i_d, i_q, u_d, "
                    f"u_q) {v['plateau_closure_median']:.2f}"
                )
                for k, s in v["plateau"].items():
                    print(
                        f"  {k:10s} rms error nominal {s['rms_nominal']:.3g}, fitted {s['rms_fitted']:.3g}, "
                        f"closure {s['closure']:.2f}"
                    )
            return 0
        if args.rig:
            return fail(
                "error",
                "--rig is for `gap record` and `gap verify`; a diagnosis reads the log (and "
                "--motor, the nominal model)",
                2,
            )
        if (
            args.target not in ACTIONS
            and not os.path.exists(args.target)
            and not args.target.endswith(".mcap")
        ):
            from pmsm_hil.names import closest

            close = closest(args.target, ACTIONS)
            if close:
                return fail(
                    "error",
                    f"{args.target}: no such file or action; did you mean "
                    f"{' or '.join(f'`gap {c}`' for c in close)}? "
                    f"(actions: {', '.join(ACTIONS)}; or a LOG.mcap to diagnose)",
                    2,
                )
        path = args.rest[0] if args.target == "augment" and args.rest else args.target
        if args.target == "augment" and (not args.rest or not args.out):
            return fail("error", "gap augment LOG.mcap -o fitted-rig.yaml", 2)
        why = path_problem(path) or (args.holdout and path_problem(args.holdout, "--holdout"))
        if args.target == "augment" and not why:
            why = _out_problem(args.out, "fitted-rig.yaml")
        if not why and args.report and args.target != "augment":
            from pmsm_hil.cli.paths import folder_problem

            report_why = folder_problem(Path(args.report))  # before the diagnosis, not after it
            why = report_why and f"--report {args.report}: {report_why}"
        if why:
            return fail("error", why, 2)
        t0 = time.monotonic()
        res, m, rec = _diagnose(args, path)
        took = time.monotonic() - t0
        for note in rec.notes:
            report("note", note)
    except (RecordError, ProfileError, LogFormatError, ValueError, KeyError) as e:
        return fail("error", str(e), 2)
    except DeviceError as e:  # record, verify: the emulator refused the run (e.g. its plant)
        return fail("error", str(e), 3)
    from pmsm_hil.gap.report import jsonable, verdict_lines, write_report

    if args.target == "augment":
        from pmsm_hil.gap.rigfile import fitted_rig

        rig = fitted_rig(res, m, args.out, getattr(rec, "sensor_spec", {}))
        print(f"{args.out}: {', '.join(rig['effects']) or 'no effect'}")
        return 0
    fitted = None
    if args.report:
        write_report(res, args.report)
        if "effects" in res:  # control-rate data: the selected effects as a rig file beside it
            from pmsm_hil.gap.rigfile import fitted_rig

            fitted = os.path.join(args.report, "fitted-rig.yaml")
            fitted_rig(res, m, fitted, getattr(rec, "sensor_spec", {}))
    if args.json:
        print(json.dumps(jsonable(res)))
    else:
        for line in verdict_lines(res):  # steady-state data: the fitted values and the gap
            print(line)
        if fitted:
            check = (
                f"check it: pmsm-hil gap verify {path} --rig {fitted}"
                if _reruns(path)
                else "gap verify re-runs a pmsm-hil run log's own profile; this log carries none"
            )
            print(f"report {args.report}; the fitted effects as a rig file: {fitted} ({check})")
        if "discretisation_gap" in res:
            n = _workers(args)
            print(f"diagnosed in {took:.0f} s with {n} fit process{'es' if n > 1 else ''}")
    sys.stdout.flush()
    return 0
