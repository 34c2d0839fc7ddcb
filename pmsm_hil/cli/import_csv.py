"""`pmsm-hil import FILE.csv --motor M.yaml -o OUT.mcap`: external data for the gap diagnosis."""

from __future__ import annotations

import argparse

from pmsm_hil.cli.errors import fail

# the sample times a control-rate CSV may have (pmsm_hil.gap.csv_import.TS_MIN_S, TS_MAX_S; not
# imported from there: that module imports numpy)
TS_MIN_US, TS_MAX_MS = 1.0, 1.0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "import",
        help="import control-rate or steady-state dq data from a CSV (docs/gap.md)",
        description="Reads a CSV (a header row, SI units, the project's column names, # comment "
        "lines allowed; UTF-8, with or without a byte-order mark) into an MCAP log for `pmsm-hil "
        "gap`. Control-rate data, one row per control period (t_s, the sample time, within "
        f"{TS_MIN_US:g} us .. {TS_MAX_MS:g} ms): t_s, i_a_a, i_b_a, theta_e_rad and one voltage "
        "group: s_a s_b s_c with v_dc_v, d_a d_b d_c with v_dc_v, or u_alpha_v u_beta_v; "
        "optional i_c_a, v_dc_v, omega_e_rad_s, load_nm, temp_winding_c, temp_magnet_c, pwm_on. "
        "Steady-state dq data: t_s, u_d_v, u_q_v, i_d_a, i_q_a and omega_e_rad_s or speed_rpm; "
        'optional temp_winding_c, temp_magnet_c, torque_nm. Details: docs/gap.md, "CSV import".',
    )
    p.add_argument("csv", help="CSV file: a header row, SI units, the project's column names")
    p.add_argument(
        "--motor",
        required=True,
        help="motor file the data belongs to (a path, or a shipped motor by its name)",
    )
    p.add_argument("-o", "--out", required=True, help="MCAP log to write, *.mcap")
    p.add_argument("--overwrite", action="store_true", help="replace a log already at -o")


def main(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pmsm_hil.cli.paths import check_output

    code = check_output(
        Path(args.out), "-o", (".mcap",), "the log is MCAP", overwrite=args.overwrite
    )
    if code is not None:
        return code
    from pmsm_hil.gap.csv_import import CsvImportError, import_csv
    from pmsm_hil.profiles import ProfileError

    try:
        from pmsm_hil.profiles.shipped import resolve

        s = import_csv(args.csv, resolve(args.motor, "motor"), args.out)
    except (CsvImportError, ProfileError) as e:
        return fail("error", str(e), 2)
    ts = f", sample time {s['ts_s']:.6g} s" if s["ts_s"] else ""
    print(f"{args.out}: {s['rows']} rows of {s['kind']} data{ts} ({s['topic']})")
    return 0
