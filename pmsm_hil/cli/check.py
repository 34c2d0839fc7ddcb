"""`pmsm-hil check PROFILE`: validate a profile with its motor and rig files without running it."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from pmsm_hil.cli.errors import fail, report

if TYPE_CHECKING:
    from pmsm_hil.profiles import Profile


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "check",
        help="validate a profile with its motor and rig files, without running it",
        description="Loads PROFILE with its motor and rig files (or --motor/--rig), as `run` "
        "does before it opens the device, and prints every problem (exit 2) or warning, then "
        "what the motor file's numbers give: the back-EMF at speed_max_rpm against the DC link, "
        "the torque at i_max_a and the MPCC's current step. Nothing is started.",
    )
    p.add_argument("profile", help="profile YAML, or the name of a shipped profile")
    p.add_argument("--motor", help="motor file (or shipped name) instead of the profile's")
    p.add_argument("--rig", help="rig file (or shipped name) instead of the profile's")


def figures(profile: Profile) -> list[str]:
    """What the motor file's numbers give on the run's DC link, in the units an engineer checks
    against a datasheet (docs/profiles.md, "From a datasheet")."""
    from pmsm_hil.profiles.current_step import current_step

    m = profile.motor
    reach_v = profile.v_dc_v / math.sqrt(3.0)
    emf_v = m.psi_f_wb * m.pole_pairs * m.speed_max_rpm * math.pi / 30.0
    i_d, i_q = m.mtpa_currents(m.i_max_a)
    step = current_step(profile)
    ke_ll_rms = m.psi_f_wb * m.pole_pairs * 104.72 / math.sqrt(2.0 / 3.0)
    return [
        f"back-EMF at speed_max_rpm {m.speed_max_rpm:g} r/min: {emf_v:.4g} V peak phase, "
        f"{100 * emf_v / reach_v:.3g} % of the {reach_v:.4g} V that v_dc_v {profile.v_dc_v:g} V "
        f"gives (v_dc_v / sqrt 3); Ke {ke_ll_rms:.4g} V/krpm line-line rms, "
        f"{ke_ll_rms * math.sqrt(2.0):.4g} peak",
        f"torque at i_max_a {m.i_max_a:g} A on MTPA: {m.torque_mtpa_nm(m.i_max_a):.4g} N m "
        f"(i_d {i_d:.3g} A, i_q {i_q:.3g} A; torque_max_nm {m.torque_max_nm:g}); "
        f"Kt {m.k_t_nm_per_a * math.sqrt(2.0):.4g} N m/A rms",
        f"MPCC current step 2/3 v_dc ts_s / min(L_d, L_q): {step.step_a:.3g} A, "
        f"{100 * step.share:.3g} % of i_max_a",
    ]


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.profiles import ProfileError, load_profile
    from pmsm_hil.profiles.shipped import resolve

    try:
        path = resolve(args.profile, "profile")
        rig = resolve(args.rig, "rig") if args.rig else None
        motor = resolve(args.motor, "motor") if args.motor else None
        profile = load_profile(path, rig_override=rig, motor_override=motor)
    except ProfileError as e:  # its text lists the problems, then any warnings
        return fail("error", str(e), 2)
    for w in profile.warnings:
        report("warning", w)
    n = len(profile.segments)
    print(
        f"{'ok' if not profile.warnings else 'ok, with warnings'}: {profile.path} (motor "
        f"{profile.motor.path}, rig {profile.rig.path}): {n} segment{'s' * (n != 1)}, "
        f"{profile.total_duration_s:g} s"
    )
    for line in figures(profile):
        print(f"  {line}")
    return 0
