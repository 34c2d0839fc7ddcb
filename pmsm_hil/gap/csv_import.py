"""`pmsm-hil import FILE.csv --motor M.yaml -o OUT.mcap`: external data into a log the gap diagnosis
reads (docs/gap.md, "CSV import").

A header row, SI units, the project's column names; UTF-8 with or without a byte-order mark (Excel's
"CSV UTF-8"). Control-rate data becomes `/pmsm/control_rate`, steady-state dq data `/pmsm/steady_dq`.
Nothing is guessed: unknown or missing columns, a value that is not a number, time that does not
increase, or (control rate) a sampling gap or a sample time that is no control period is an error
that names the file, line and column, with the value as the file writes it.
"""

from __future__ import annotations

import csv
import math
import os
from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.gap.record import CONTROL_TOPIC, GAP_TOPICS, STEADY_TOPIC

if TYPE_CHECKING:
    from pmsm_hil.profiles import Motor

CONTROL_REQUIRED = ("t_s", "i_a_a", "i_b_a", "theta_e_rad")
CONTROL_VOLTAGE = (("s_a", "s_b", "s_c"), ("d_a", "d_b", "d_c"), ("u_alpha_v", "u_beta_v"))
CONTROL_OPTIONAL = (
    "i_c_a",
    "v_dc_v",
    "omega_e_rad_s",
    "load_nm",
    "temp_winding_c",
    "temp_magnet_c",
    "pwm_on",
)
STEADY_REQUIRED = ("t_s", "u_d_v", "u_q_v", "i_d_a", "i_q_a")
STEADY_SPEED = ("omega_e_rad_s", "speed_rpm")
STEADY_OPTIONAL = ("temp_winding_c", "temp_magnet_c", "torque_nm")
# columns that may be left out: one with no value in any row (empty cells or nan, as a log's
# "NaN = not given" columns export, e.g. pandas' to_csv of /pmsm/control_rate) is taken as absent
NOT_GIVEN_OK = (
    {c for g in CONTROL_VOLTAGE for c in g}
    | set(CONTROL_OPTIONAL)
    | set(STEADY_SPEED)
    | set(STEADY_OPTIONAL)
)
NOT_GIVEN_TEXT = ("", "nan")  # a cell that holds no value (compared without case)
# a control-rate record has one row per control period: PWM at 1 kHz .. 1 MHz. A step of t_s
# outside is a unit mistake (t_s in ms or us) or not control-rate data (pmsm_hil/cli/import_csv.py
# quotes these in its --help)
TS_MIN_S, TS_MAX_S = 1e-6, 1e-3
# a flux map's columns (pmsm_hil/profiles/fluxmap.py): such a file is not imported but named
FLUX_MAP_COLUMNS = ("i_d_a", "i_q_a", "psi_d_wb", "psi_q_wb")
# a current or voltage this many times the motor file's trip current or over-voltage trip is a
# unit mistake (mA, mV), not a measurement
UNIT_FACTOR = 10.0
# omega_e_rad_s against theta_e_rad's rate over the file (_check_speed): a speed in r/min or the
# mechanical one is off by 60/(2 pi p) or 1/p, far beyond a filtered or estimated speed's mean
SPEED_REL = 0.1
SPEED_FLOOR_RAD_S = 5.0


class CsvImportError(ValueError):
    """A CSV that cannot be imported; the message names file, line and column."""


def _kind(path: str, header: list[str], hline: int = 1, blank: list[str] | None = None) -> str:
    """ "control" or "steady" from the header row (line ``hline`` of the file); ``blank``: the
    columns left out because no row gives them a value (named in a missing-column error)."""
    cols = set(header)
    if len(header) == 1 and (sep := next((c for c in ";\t|" if c in header[0]), None)):
        raise CsvImportError(
            f"{path}: line {hline}: the header {header[0]!r} is one column: the separator is a "
            f"comma, not {sep!r}"
        )
    empty = [j + 1 for j, c in enumerate(header) if not c]
    if empty:
        raise CsvImportError(
            f"{path}: line {hline}: column {', '.join(map(str, empty))} of the header has no name "
            "(a trailing or doubled separator?)"
        )
    dup = sorted({c for c in header if header.count(c) > 1})
    if dup:
        raise CsvImportError(
            f"{path}: line {hline}: column(s) {', '.join(dup)} appear more than once"
        )
    if set(FLUX_MAP_COLUMNS) <= cols:
        raise CsvImportError(
            f"{path}: line {hline}: a flux map ({', '.join(FLUX_MAP_COLUMNS)}), not control-rate "
            "or steady-state data: a motor file's flux_map or a rig's saturation map takes it "
            "(docs/profiles.md, docs/rigs.md)"
        )
    if {"u_d_v", "u_q_v", "i_d_a", "i_q_a"} & cols and not {"i_a_a", "i_b_a"} & cols:
        missing = [c for c in STEADY_REQUIRED if c not in cols]
        if not any(c in cols for c in STEADY_SPEED):
            missing.append("omega_e_rad_s or speed_rpm")
        known = set(STEADY_REQUIRED) | set(STEADY_SPEED) | set(STEADY_OPTIONAL)
        kind = "steady-state dq"
    else:
        missing = [c for c in CONTROL_REQUIRED if c not in cols]
        groups = [g for g in CONTROL_VOLTAGE if all(c in cols for c in g)]
        if not groups:
            missing.append("the applied voltage (s_a s_b s_c, d_a d_b d_c or u_alpha_v u_beta_v)")
        elif groups[0] != CONTROL_VOLTAGE[2] and "v_dc_v" not in cols:
            missing.append("v_dc_v (needed with switch states or duties)")
        known = (
            set(CONTROL_REQUIRED) | {c for g in CONTROL_VOLTAGE for c in g} | set(CONTROL_OPTIONAL)
        )
        kind = "control-rate"
    unknown = [c for c in header if c not in known]
    problems = []
    if unknown:
        problems.append(f"unknown column(s) {', '.join(unknown)}")
    if missing:
        problems.append(f"missing column(s) {', '.join(missing)}")
        if blank:
            problems[-1] += f" (without a value in any row, so not given: {', '.join(blank)})"
    if problems:
        raise CsvImportError(
            f"{path}: line {hline}: {kind} data: {'; '.join(problems)} (columns and units: "
            "docs/gap.md)"
        )
    return "steady" if kind.startswith("steady") else "control"


def read_csv(
    path: str | os.PathLike, motor: Motor | None = None
) -> tuple[str, dict[str, np.ndarray]]:
    """(kind, columns) with kind "control" or "steady"; raises CsvImportError. With the motor file
    the data belongs to, values its drive cannot have (a unit mistake) are errors too."""
    path = os.fspath(path)
    try:
        # utf-8-sig: a leading byte-order mark (Excel's "CSV UTF-8") is not part of the header
        f = open(path, newline="", encoding="utf-8-sig")  # noqa: SIM115  (closed by `with f:`)
    except OSError as e:
        raise CsvImportError(f"{path}: cannot read ({e.strerror})") from None
    with f:
        try:
            rows = [
                (n, r)
                for n, r in enumerate(csv.reader(f), start=1)
                if r and not r[0].lstrip().startswith("#")
            ]
        except UnicodeDecodeError:
            # the decoder's offset counts from the chunk it was reading: find the file's own
            # (a byte-order mark is valid UTF-8, so plain utf-8 gives the offset in the file)
            with open(path, "rb") as b:
                raw = b.read()
            try:
                raw.decode("utf-8")
            except UnicodeDecodeError as e:
                from pmsm_hil.files import octet_position

                line, _ = octet_position(raw, e.start)
                raise CsvImportError(
                    f"{path}: line {line}: not UTF-8 text (octet {e.start} = "
                    f"0x{raw[e.start]:02x}: {e.reason}); save it as CSV UTF-8"
                ) from None
            raise CsvImportError(f"{path}: not UTF-8 text; save it as CSV UTF-8") from None
    if not rows:
        raise CsvImportError(f"{path}: empty file (a header row and data rows are needed)")
    hline, header = rows[0]
    header = [h.strip() for h in header]
    data = rows[1:]
    blank = _not_given(header, data)
    if blank:  # no value in any row: as if the column were not there
        keep = [j for j, h in enumerate(header) if h not in blank]
        header = [header[j] for j in keep]
        data = [(n, [r[j] for j in keep]) for n, r in data]
    kind = _kind(path, header, hline, blank)
    if len(data) < 3:
        raise CsvImportError(f"{path}: only {len(data)} data row(s); at least 3 are needed")
    vals = np.empty((len(data), len(header)))
    for i, (line, r) in enumerate(data):
        if len(r) != len(header):
            raise CsvImportError(f"{path}: line {line}: {len(r)} values for {len(header)} columns")
        for j, v in enumerate(r):
            try:
                x = float(v)
            except ValueError:
                raise CsvImportError(
                    f"{path}: line {line}: {header[j]} = {v.strip()!r} is not a number"
                ) from None
            if not math.isfinite(x):
                raise CsvImportError(
                    f"{path}: line {line}: {header[j]} = {v.strip()!r} is not finite"
                )
            vals[i, j] = x
    cols = {h: vals[:, j] for j, h in enumerate(header)}
    lines = [ln for ln, _ in data]

    def cell(k: int, name: str) -> str:  # the value as the file writes it
        return data[k][1][header.index(name)].strip()

    t = cols["t_s"]
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if len(bad):
        k = int(bad[0]) + 1
        raise CsvImportError(
            f"{path}: line {lines[k]}: t_s = {cell(k, 't_s')} does not increase (previous "
            f"{cell(k - 1, 't_s')})"
        )
    if kind == "control":
        ts = float(np.median(dt))
        if not TS_MIN_S <= ts <= TS_MAX_S:
            units = (("milliseconds", 1e-3), ("microseconds", 1e-6))
            hint = next(
                (
                    f" — is it written in {unit} ({ts * f * 1e6:.6g} us a period)?"
                    for unit, f in units
                    if TS_MIN_S <= ts * f <= TS_MAX_S
                ),
                "",
            )
            raise CsvImportError(
                f"{path}: line {lines[1]}: t_s = {cell(1, 't_s')}: the sample time from t_s is "
                f"{ts:.6g} s, not a control period ({TS_MIN_S:g} .. {TS_MAX_S:g} s: one row per "
                f"PWM period); t_s is in seconds{hint}"
            )
        gap = np.nonzero(np.abs(dt - ts) > 0.01 * ts)[0]
        if len(gap):
            k = int(gap[0]) + 1
            raise CsvImportError(
                f"{path}: line {lines[k]}: t_s = {cell(k, 't_s')} leaves a gap of "
                f"{dt[k - 1]:.6g} s after {cell(k - 1, 't_s')}; the sample time from t_s is "
                f"{ts:.6g} s (±1 %) ({len(gap)} such step(s); split the file at the gaps)"
            )
        for c in ("s_a", "s_b", "s_c", "pwm_on"):
            if c in cols and np.any((cols[c] != 0) & (cols[c] != 1)):
                k = int(np.nonzero((cols[c] != 0) & (cols[c] != 1))[0][0])
                raise CsvImportError(f"{path}: line {lines[k]}: {c} = {cell(k, c)} is not 0 or 1")
        for c in ("d_a", "d_b", "d_c"):
            if c in cols and np.any((cols[c] < 0) | (cols[c] > 1)):
                k = int(np.nonzero((cols[c] < 0) | (cols[c] > 1))[0][0])
                raise CsvImportError(
                    f"{path}: line {lines[k]}: {c} = {cell(k, c)} is not in [0, 1]"
                )
        if "theta_e_rad" in cols:  # a wrapped angle steps by at most one turn between two rows
            step = np.abs(np.diff(cols["theta_e_rad"]))
            far = np.nonzero(step > 2 * np.pi * 1.01)[0]
            if len(far):
                k = int(far[0]) + 1
                raise CsvImportError(
                    f"{path}: line {lines[k]}: theta_e_rad = {cell(k, 'theta_e_rad')} after "
                    f"{cell(k - 1, 'theta_e_rad')}: a step of more than one turn (2 pi rad) in "
                    "one row; theta_e_rad is in radians — is it written in degrees?"
                )
            if "omega_e_rad_s" in cols:
                _check_speed(path, hline, t, cols["theta_e_rad"], cols["omega_e_rad_s"])
    if motor is not None:
        _check_units(path, cols, lines, cell, motor)
    return kind, cols


def _not_given(header: list[str], data: list[tuple[int, list[str]]]) -> list[str]:
    """The columns of NOT_GIVEN_OK whose every cell holds no value (NOT_GIVEN_TEXT); none when a
    row has another number of values than the header (reported as such)."""
    out = []
    for j, h in enumerate(header):
        if h in NOT_GIVEN_OK and all(
            len(r) == len(header) and r[j].strip().lower() in NOT_GIVEN_TEXT for _, r in data
        ):
            out.append(h)
    return out if data else []


def _check_speed(path, hline: int, t, theta, omega) -> None:
    """omega_e_rad_s is the rate at which theta_e_rad turns: their means over the file agree
    within SPEED_REL (or SPEED_FLOOR_RAD_S near standstill), else a unit mistake is named (r/min,
    or the mechanical speed: 60/(2 pi p) or 1/p of it)."""
    turned = np.unwrap(theta)
    rate = float(turned[-1] - turned[0]) / float(t[-1] - t[0])
    mean = float(np.mean(omega))
    if abs(mean - rate) <= max(SPEED_REL * max(abs(rate), abs(mean)), SPEED_FLOOR_RAD_S):
        return
    raise CsvImportError(
        f"{path}: line {hline}: column omega_e_rad_s averages {mean:.5g} where theta_e_rad "
        f"turns at {rate:.5g} rad/s over the file; omega_e_rad_s is the electrical speed in "
        "rad/s — is it written in r/min, or is it the mechanical speed?"
    )


def _check_units(path, cols, lines, cell, motor: Motor) -> None:
    """A current or voltage beyond UNIT_FACTOR times what the motor file's drive trips at."""
    v_max = motor.v_dc_max_v
    limits = [
        (c, motor.i_trip_a, "i_trip_a", "A", "mA")
        for c in ("i_a_a", "i_b_a", "i_c_a", "i_d_a", "i_q_a")
    ] + [
        (c, v_max, "v_dc_max_v", "V", "mV")
        for c in ("v_dc_v", "u_alpha_v", "u_beta_v", "u_d_v", "u_q_v")
    ]
    for c, lim, field, unit, small in limits:
        if c not in cols:
            continue
        over = np.nonzero(np.abs(cols[c]) > UNIT_FACTOR * lim)[0]
        if len(over):
            k = int(over[0])
            raise CsvImportError(
                f"{path}: line {lines[k]}: {c} = {cell(k, c)} is more than {UNIT_FACTOR:g} times "
                f"the motor file's {field} ({lim:g} {unit}): {c} is in {unit} — is it written in "
                f"{small}?"
            )


def import_csv(
    path: str | os.PathLike, motor_path: str | os.PathLike, out_path: str | os.PathLike
) -> dict[str, object]:
    """Read the CSV, check it against the motor file and write the log; returns a summary."""
    from pmsm_hil.log.writer import LogWriter
    from pmsm_hil.profiles import load_motor

    motor = load_motor(motor_path)
    kind, cols = read_csv(path, motor)
    n = len(cols["t_s"])
    meta = {
        "gap_source": {
            "kind": "csv",
            "file": os.path.basename(os.fspath(path)),
            "motor": motor.name,
        }
    }
    with open(motor_path, "rb") as f:
        atts = [("motor.yaml", "application/yaml", f.read())]
    if kind == "control":
        ts = float(np.median(np.diff(cols["t_s"])))
        meta["gap_source"]["ts_s"] = repr(ts)
        names = [fd.name for fd in GAP_TOPICS[0].fields]
        rows = {k: cols.get(k, np.full(n, np.nan)) for k in names}
        topic = CONTROL_TOPIC
    else:
        if "omega_e_rad_s" not in cols:
            cols["omega_e_rad_s"] = cols["speed_rpm"] * motor.pole_pairs * 2 * np.pi / 60.0
        names = [fd.name for fd in GAP_TOPICS[1].fields]
        rows = {k: cols.get(k, np.full(n, np.nan)) for k in names}
        topic = STEADY_TOPIC
        ts = None
    t0 = float(cols["t_s"][0])
    if t0 < 0:
        rows["t_s"] = rows["t_s"] - t0
    with LogWriter(out_path, meta, atts, topics=GAP_TOPICS) as w:
        w.write_many(topic, rows)
    return {"kind": kind, "rows": n, "ts_s": ts, "topic": topic}
