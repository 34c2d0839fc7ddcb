"""`pmsm-hil bench identify`: paper A's identification run on the emulator, Table 2 beside ours."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.cli.errors import SCHEDULER_ERRORS, fail, scheduler_failed
from pmsm_hil.seeds import SEED_MAX, seed_arg

SEEDS_HELP = (
    f"N, A-B (A <= B) or a comma-separated list of them, whole numbers 0..{SEED_MAX}, none twice, "
    "e.g. 1-10 or 1,2,5"
)

if TYPE_CHECKING:
    from pmsm_hil.bench.trials import Cluster


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "bench",
        help="reproducible benchmarks on the emulator (identify: paper A Table 2; sensorless: "
        "angle estimators closing the loop)",
    )
    bsub = p.add_subparsers(dest="bench", required=True, metavar="BENCH")
    b = bsub.add_parser(
        "identify",
        help="online identification: RLS, Adaline, NLMS-Adaline vs paper A Table 2",
        description="Runs an identification profile (paper-a-identify, or --profile) on the "
        "emulator (a few seconds) and prints the final estimates and convergence times of RLS, "
        "Adaline and NLMS-Adaline beside the truth (for paper A's motor, beside its Table "
        "2 too); writes the log, the convergence plot and the table into --out. --mismatch, "
        "--per-effect and --rigs add runs on a local Dask cluster, with a progress bar "
        "(docs/identification.md).",
    )
    b.add_argument(
        "--profile",
        default=None,
        help="profile file or shipped name, one with control.identify: true (default: the shipped "
        "paper-a-identify)",
    )
    b.add_argument(
        "--out",
        "-o",
        default="runs/bench-identify",
        help="directory for the log, the convergence plot (PNG) and the table (markdown; default "
        "runs/bench-identify)",
    )
    b.add_argument(
        "--seed",
        type=seed_arg,
        default=None,
        metavar="N",
        help="emulator noise seed of the Table-2, --mismatch and --per-effect runs (default 1; "
        "--rigs and --per-effect --commissioned take --seeds)",
    )
    b.add_argument("--rig", default=None, help="rig file for the emulator (default: the profile's)")
    b.add_argument(
        "--motor",
        default=None,
        help="motor file instead of the profile's, e.g. a commissioned one (pmsm-hil commission)",
    )
    b.add_argument(
        "--until",
        type=float,
        default=None,
        metavar="S",
        help="evaluate the table up to device time S (default: the end of the last segment "
        "before any drift step)",
    )
    b.add_argument(
        "--mismatch",
        action="store_true",
        help="also the mismatch benchmark: i_d/i_q tracking-error RMS at 1000 r/min under load "
        "with the predictor at the true parameters, frozen 50 %% off, and fed by NLMS-Adaline",
    )
    b.add_argument(
        "--per-effect",
        action="store_true",
        help="also the identification results on each rig effect alone (profiles/rigs/effect-*.yaml), "
        "as a markdown table (about a minute)",
    )
    b.add_argument(
        "--rigs",
        default=None,
        help="comma-separated rigs: one identification table per rig, median and worst over "
        "--seeds (e.g. default,lab-typical)",
    )
    b.add_argument(
        "--seeds",
        default=None,
        metavar="SEEDS",
        help=f"seeds for --rigs (default 1-10) and --per-effect --commissioned (default 1-2): "
        f"{SEEDS_HELP}",
    )
    b.add_argument(
        "--commissioned",
        action="store_true",
        help="with --rigs or --per-effect: commission each rig and seed first and identify with "
        "that motor file",
    )
    b.add_argument(
        "--only",
        choices=("mismatch", "per-effect"),
        default=None,
        help="run only that part (skips the Table-2 run)",
    )
    _cluster_args(b, "--rigs / --mismatch / --per-effect runs")

    c = bsub.add_parser(
        "commission",
        help="commissioning on the emulator: errors per step over rigs and seeds vs the targets",
        description="Commissions the emulated drive on every rig and seed (one trial each, on a "
        "local Dask cluster: docs/sweep.md) and tables each step's errors against the plant, "
        "median and worst over the seeds, beside the targets (docs/commissioning.md). --rigs and "
        "--seeds make it smaller.",
    )
    c.add_argument(
        "--rigs",
        default="default,lab-typical",
        help="comma-separated rigs (shipped names or files; default default,lab-typical)",
    )
    c.add_argument(
        "--motor",
        default=None,
        help="nominal motor file or shipped name, as `pmsm-hil commission --motor` (default: "
        "paper-a-ipmsm); every rig must suit it (its v_dc_v, effects)",
    )
    c.add_argument(
        "--seeds", default="1-10", metavar="SEEDS", help=f"seeds (default 1-10): {SEEDS_HELP}"
    )
    c.add_argument(
        "--out",
        "-o",
        default="runs/bench-commission",
        help="directory for logs, table (default runs/bench-commission)",
    )
    _cluster_args(c, "the rigs' and seeds' runs")
    s = bsub.add_parser(
        "sensorless",
        help="sensorless estimators closing the loop: angle and speed errors per scenario and rig "
        "(median and worst over seeds) beside the papers' figures, with plots",
        description="Runs the sensorless scenarios (paper-b, paper-a-sensorless) on every rig and "
        "seed (12 runs by default, on a local Dask cluster, with a progress bar) and writes the "
        "angle and speed errors per scenario and rig, median and worst over the seeds, beside the "
        "papers' figures, with plots (docs/sensorless-bench.md). --only, --rigs and --seeds make "
        "it smaller, e.g. --only paper-b --rigs default --seeds 11.",
    )
    s.add_argument(
        "--out",
        "-o",
        default="runs/bench-sensorless",
        help="directory for logs, table, plots (default runs/bench-sensorless)",
    )
    s.add_argument(
        "--seeds",
        default="11,12,13",
        metavar="SEEDS",
        help=f"seeds (default 11,12,13): {SEEDS_HELP}",
    )
    s.add_argument(
        "--rigs",
        default="default,lab-typical",
        help="comma-separated rigs (shipped names or files; default default,lab-typical)",
    )
    s.add_argument(
        "--only",
        default=None,
        metavar="TEXT",
        help="only the scenarios whose profile or name contains TEXT (none: exit 2 listing them)",
    )
    _cluster_args(s, "the scenarios' runs")


def _cluster_args(p: argparse.ArgumentParser, what: str) -> None:
    """--workers / --scheduler: where a benchmark's runs go (pmsm_hil.bench.trials)."""
    p.add_argument(
        "--workers",
        type=_workers,
        default=None,
        metavar="N",
        help=f"{what}: worker processes of the local Dask cluster (default: one per core; "
        "docs/sweep.md)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDR",
        help=f"{what} on this Dask scheduler, e.g. tcp://HOST:8786 (the output folder must be on "
        "a filesystem the workers share)",
    )


def _workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give a whole number of workers, at least 1")
    return n


def _cluster(args: argparse.Namespace) -> Cluster:
    from pmsm_hil.bench.trials import Cluster

    return Cluster(workers=args.workers, scheduler=args.scheduler, progress=True)


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.bench.identify import BenchError
    from pmsm_hil.bench.trials import BenchInputError, parse_rigs, parse_seeds
    from pmsm_hil.profiles import ProfileError

    # --seeds and --rigs of every benchmark, checked once before anything runs
    try:
        seeds = parse_seeds(args.seeds) if args.seeds is not None else None
    except BenchInputError as e:
        return fail("error", f"--seeds {args.seeds}: {e}", 2)
    try:
        rigs = parse_rigs(args.rigs) if args.rigs is not None else None
    except BenchInputError as e:
        return fail("error", f"--rigs {args.rigs}: {e}", 2)
    try:
        if args.bench == "sensorless":
            return _sensorless(args, seeds or [], rigs or [])
        if args.bench == "commission":
            from pmsm_hil.bench.commission import bench_commission

            bench_commission(
                rigs or [], seeds or [], Path(args.out), cluster=_cluster(args), motor=args.motor
            )
            return 0
        return _identify(args, seeds, rigs)
    except (ProfileError, BenchInputError) as e:
        return fail("error", str(e), 2)
    except BenchError as e:
        return fail("error", str(e), 3)
    except SCHEDULER_ERRORS as e:
        if not args.scheduler:
            raise
        return scheduler_failed(args.scheduler, e)


def _identify(args: argparse.Namespace, seeds: list[int] | None, rigs: list[str] | None) -> int:
    from pmsm_hil.bench.identify import (
        check_profile,
        default_profile,
        identify,
        mismatch,
        per_effect,
    )
    from pmsm_hil.bench.trials import BenchInputError
    from pmsm_hil.profiles.shipped import resolve

    effects = args.per_effect or args.only == "per-effect"
    if seeds is not None and not rigs and not (effects and args.commissioned):
        return fail(
            "error",
            f"--seeds {args.seeds}: only with --rigs or --per-effect --commissioned (the Table-2, "
            "--mismatch and --per-effect runs take one --seed N)",
            2,
        )
    unused = _unused_option(args, effects)
    if unused:
        return fail("error", unused, 2)
    seed = 1 if args.seed is None else args.seed
    path = resolve(args.profile, "profile") if args.profile else default_profile()
    rig = resolve(args.rig, "rig") if args.rig else None
    motor = resolve(args.motor, "motor") if args.motor else None
    try:
        check_profile(path, rig, motor)
    except BenchInputError as e:
        return fail("error", f"--profile {args.profile or 'paper-a-identify'}: {e}", 2)
    out = Path(args.out)
    if effects and args.commissioned:
        from pmsm_hil.bench.identify_rigs import per_effect_commissioned

        per_effect_commissioned(path, seeds or [1, 2], out, cluster=_cluster(args))
        return 0
    if rigs:
        from pmsm_hil.bench.identify_rigs import identify_rigs

        identify_rigs(
            path,
            rigs,
            seeds or list(range(1, 11)),
            out,
            commissioned=args.commissioned,
            motor=motor,
            cluster=_cluster(args),
        )
        return 0
    cluster = _cluster(args)
    if args.only not in {"per-effect", "mismatch"}:
        identify(path, out, seed, rig, args.until, motor=motor)
    if args.mismatch or args.only == "mismatch":
        out.mkdir(parents=True, exist_ok=True)
        mismatch(path, out, seed, cluster=cluster)
    if args.per_effect or args.only == "per-effect":
        out.mkdir(parents=True, exist_ok=True)
        per_effect(path, out, seed, cluster=cluster)
    return 0


def _sensorless(args: argparse.Namespace, seeds: list[int], rigs: list[str]) -> int:
    from pmsm_hil.bench.sensorless import select
    from pmsm_hil.bench.sensorless_report import sensorless
    from pmsm_hil.bench.trials import BenchInputError

    try:
        select(args.only)
    except BenchInputError as e:
        return fail("error", f"--only {args.only}: {e}", 2)
    sensorless(Path(args.out), tuple(seeds), tuple(rigs), args.only, cluster=_cluster(args))
    return 0


def _unused_option(args: argparse.Namespace, effects: bool) -> str | None:
    """The first option given that the chosen part of `bench identify` would not use: refused
    rather than ignored (a walk found `--commissioned` alone running the nominal motor file and
    `--rigs R --mismatch` leaving the mismatch out, both with exit 0)."""
    given = {
        "--rig": args.rig is not None,
        "--motor": args.motor is not None,
        "--until": args.until is not None,
        "--seed": args.seed is not None,
        "--mismatch": args.mismatch,
        "--per-effect": args.per_effect,
        "--only": args.only is not None,
        "--rigs": args.rigs is not None,
    }
    if effects and args.commissioned:
        mode, takes = "--per-effect --commissioned", "--seeds and --profile"
        unused = ["--rigs", "--rig", "--motor", "--until", "--seed", "--mismatch"]
        given["--mismatch"] = args.mismatch or args.only == "mismatch"
    elif args.rigs is not None:
        mode, takes = "--rigs", "--seeds, --commissioned, --motor and --profile"
        unused = ["--rig", "--until", "--seed", "--mismatch", "--per-effect", "--only"]
    elif args.commissioned:
        return (
            "--commissioned: only with --rigs or --per-effect (each rig and seed is commissioned "
            "first); for the Table-2 run give --motor a file of `pmsm-hil commission`"
        )
    elif args.only is not None:
        mode, takes = f"--only {args.only}", "--seed and --profile (no Table-2 run)"
        unused = ["--rig", "--motor", "--until"]
    else:
        return None
    for opt in unused:
        if given[opt]:
            return f"{opt}: not with {mode}, which takes {takes}; leave it out or run it apart"
    return None
