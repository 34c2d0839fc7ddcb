"""`pmsm-hil bench identify`: paper A's identification run on the emulator, Table 2 beside ours."""
from __future__ import annotations

import argparse
from pathlib import Path

from pmsm_hil.cli.errors import fail


def add_parser(sub) -> None:
    p = sub.add_parser("bench", help="reproducible benchmarks on the emulator (identify: paper A Table 2)")
    bsub = p.add_subparsers(dest="bench", required=True, metavar="BENCH")
    b = bsub.add_parser("identify", help="online identification: RLS, Adaline, NLMS-Adaline vs paper A Table 2")
    b.add_argument("--profile", default=None, help="profile (default: profiles/paper-a-identify.yaml)")
    b.add_argument("--out", "-o", default="runs/bench-identify",
                   help="directory for the log, the convergence plot (PNG) and the table (markdown)")
    b.add_argument("--seed", type=int, default=1)
    b.add_argument("--until", type=float, default=None, metavar="S",
                   help="evaluate the table up to device time S (default: the end of the last segment "
                        "before any drift step)")


def _default_profile() -> str:
    from pmsm_hil.profiles._base import default_file
    return default_file("paper-a-identify.yaml")


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.analysis.identification import (convergence_plot, identification_table,
                                                   markdown_table, text_table)
    from pmsm_hil.emulator.settings import emulator_settings
    from pmsm_hil.profiles import ProfileError, load_profile
    from pmsm_hil.protocol.session import Session
    from pmsm_hil.runner import RunOptions, run_profile
    from pmsm_hil.transport.inproc import InProcessTransport

    path = args.profile or _default_profile()
    try:
        profile = load_profile(path)
    except ProfileError as e:
        return fail("error", str(e), 2)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "identify.mcap"
    settings = emulator_settings(profile.motor, profile.rig, seed=args.seed, baud=profile.link.baud,
                                 ts_s=profile.control.ts_s)
    result = run_profile(profile, Session(InProcessTransport(settings)), log, RunOptions(seed=args.seed))
    if result.faults or result.error:
        return fail("error", f"the run failed ({result.error or result.faults}); log {log}", 3)
    t1 = args.until
    if t1 is None:   # before the first drift step
        drift = [s for s in profile.segments if getattr(s, "plant", None) is not None]
        t1 = drift[0].t_start_s if drift else profile.total_duration_s
    rig = ", ".join(profile.rig.enabled_effects) if hasattr(profile.rig, "enabled_effects") else ""
    print(f"bench identify: {profile.name} on the emulator (motor {profile.motor.name}, rig "
          f"{profile.rig.name}: {rig}; seed {args.seed}); estimators from zero weights")
    table = identification_table(log, 0.0, t1)
    print(text_table(table))
    md = out / "identify.md"
    md.write_text(f"# Online identification, {profile.name} (t <= {t1:g} s)\n\n" + markdown_table(table) + "\n")
    png = convergence_plot(log, out / "identify.png")
    drift = [s for s in profile.segments if getattr(s, "plant", None) is not None]
    if drift:
        d = drift[0]
        dt = identification_table(log, d.t_start_s, d.t_end_s)
        print(f"\ndrift step at t = {d.t_start_s:g} s (R x {d.plant.r_s_scale:g}, psi_f x "
              f"{d.plant.psi_f_scale:g}); convergence times from the step:")
        for c in dt.cells:
            c.conv_s = None if c.conv_s is None else c.conv_s + (c.t_first_s or d.t_start_s) - d.t_start_s
        print(text_table(dt, with_paper=False))
        md.write_text(md.read_text() + f"\n## Drift step at {d.t_start_s:g} s\n\n" + markdown_table(dt, False) + "\n")
    print(f"\nlog {log}\nplot {png}\ntable {md}")
    return 0
