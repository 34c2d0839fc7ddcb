"""`pmsm-hil bench identify`: paper A's identification run on the emulator, Table 2 beside ours."""

from __future__ import annotations

import argparse
from pathlib import Path

from pmsm_hil.cli.errors import fail


def add_parser(sub) -> None:
    p = sub.add_parser(
        "bench", help="reproducible benchmarks on the emulator (identify: paper A Table 2)"
    )
    bsub = p.add_subparsers(dest="bench", required=True, metavar="BENCH")
    b = bsub.add_parser(
        "identify", help="online identification: RLS, Adaline, NLMS-Adaline vs paper A Table 2"
    )
    b.add_argument(
        "--profile", default=None, help="profile (default: profiles/paper-a-identify.yaml)"
    )
    b.add_argument(
        "--out",
        "-o",
        default="runs/bench-identify",
        help="directory for the log, the convergence plot (PNG) and the table (markdown)",
    )
    b.add_argument("--seed", type=int, default=1)
    b.add_argument("--rig", default=None, help="rig file for the emulator (default: the profile's)")
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
        "--only",
        choices=("mismatch", "per-effect"),
        default=None,
        help="run only that part (skips the Table-2 run)",
    )
    b.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="--mismatch / --per-effect runs: worker processes of the local Dask cluster "
        "(default: one per core; docs/sweep.md)",
    )
    b.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDR",
        help="--mismatch / --per-effect runs on this Dask scheduler, e.g. tcp://HOST:8786 "
        "(the output folder must be on a filesystem the workers share)",
    )


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.bench.identify import (
        BenchError,
        Cluster,
        default_profile,
        identify,
        mismatch,
        per_effect,
    )
    from pmsm_hil.profiles import ProfileError
    from pmsm_hil.profiles.shipped import resolve

    try:
        path = resolve(args.profile, "profile") if args.profile else default_profile()
        rig = resolve(args.rig, "rig") if args.rig else None
        out = Path(args.out)
        cluster = Cluster(workers=args.workers, scheduler=args.scheduler, progress=True)
        if args.only not in {"per-effect", "mismatch"}:
            identify(path, out, args.seed, rig, args.until)
        if args.mismatch or args.only == "mismatch":
            out.mkdir(parents=True, exist_ok=True)
            mismatch(path, out, args.seed, cluster=cluster)
        if args.per_effect or args.only == "per-effect":
            out.mkdir(parents=True, exist_ok=True)
            per_effect(path, out, args.seed, cluster=cluster)
    except ProfileError as e:
        return fail("error", str(e), 2)
    except BenchError as e:
        return fail("error", str(e), 3)
    return 0
