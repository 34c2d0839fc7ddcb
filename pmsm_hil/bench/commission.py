"""`pmsm-hil bench commission`: the commissioning sequence on the emulator over several rigs and
seeds, each result scored against the plant (pmsm_hil.commission.score); one table per rig with
the median and the worst error over the seeds beside the target (docs/commissioning.md)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from pmsm_hil.commission.sequence import CommissionResult
    from pmsm_hil.profiles import Profile

# quantity -> (label, unit, scale for printing, target on |error|)
TARGETS = {
    "offset_a_a": ("sensor offset a", "mA", 1e3, 0.005),
    "offset_b_a": ("sensor offset b", "mA", 1e3, 0.005),
    "offset_c_a": ("sensor offset c", "mA", 1e3, 0.005),
    "enc_offset_deg": ("encoder offset", "deg el.", 1.0, 0.2),
    "plateau_rel": ("dead-time plateau", "%", 100.0, 0.05),
    "dead_time_rel": ("dead time alone", "%", 100.0, 0.05),
    "v_drop_v": ("device drop", "V", 1.0, 0.25),
    "r_rel": ("R (vs hot truth)", "%", 100.0, 0.02),
    "l_d_rel": ("L_d at standstill", "%", 100.0, 0.05),
    "l_q_rel": ("L_q at standstill", "%", 100.0, 0.05),
    "psi_f_rel": ("psi_f (spin)", "%", 100.0, 0.01),
}


def parse_seeds(text: str) -> list[int]:
    """ "1-10" or "1,2,5" -> seeds."""
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-", 1)
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def commission_once(
    rig_path: str | None, seed: int, log: Path, motor_path: Path | str | None = None
) -> tuple[Profile, CommissionResult, dict[str, float]]:
    """One in-process commissioning run: (result, errors against the plant)."""
    from pmsm_hil.commission.score import commission_errors
    from pmsm_hil.commission.sequence import commission_profile, run_commission
    from pmsm_hil.device import DeviceSpec, open_device
    from pmsm_hil.protocol.session import Session
    from pmsm_hil.runner import RunOptions

    profile = commission_profile(motor_path, rig_path)
    link = open_device(DeviceSpec(in_process=True, seed=seed), profile)
    try:
        res = run_commission(profile, Session(link), log, RunOptions(seed=seed))
    finally:
        link.close()
    errs: dict[str, float] = (
        commission_errors(log, res.quantities, profile.rig, profile.control.ts_s) if res.ok else {}
    )
    return profile, res, errs


def table(rig_name: str, runs: list[tuple[int, CommissionResult, dict[str, float]]]) -> str:
    """Markdown: per quantity, target, median and worst |error|, seeds within the target."""
    n = len(runs)
    ok = [r for r in runs if r[1].ok]
    lines = [
        f"### rig {rig_name}: {len(ok)} of {n} seeds completed",
        "",
        "| quantity | target | median abs error | worst abs error | within target |",
        "|---|---|---|---|---|",
    ]
    for key, (label, unit, k, target) in TARGETS.items():
        vals = np.array([abs(e[key]) for _s, _r, e in ok if key in e])
        if vals.size == 0:
            continue
        within = int(np.sum(vals <= target))
        lines.append(
            f"| {label} | {target * k:g} {unit} | {np.median(vals) * k:.3g} {unit} | "
            f"{vals.max() * k:.3g} {unit} | {within}/{vals.size} |"
        )
    for s, r, _e in runs:
        if not r.ok:
            lines.append(f"\nseed {s}: {r.failure or r.run.stop_reason}")
    return "\n".join(lines)


def bench_commission(
    rigs: list[str], seeds: list[int], out: Path, echo: Callable[[str], None] = print
) -> str:
    """Runs every (rig, seed), prints and writes the tables (out/commission.md)."""
    from pmsm_hil.profiles.shipped import resolve

    out.mkdir(parents=True, exist_ok=True)
    parts = [
        f"# Commissioning on the emulator, seeds {seeds[0]}..{seeds[-1]} ({len(seeds)} seeds)",
        "",
        "Errors against the plant: sensor offsets and the encoder offset absolute, the rest "
        "relative; R against the winding's temperature-dependent truth during the R step, L_d "
        "and L_q against the incremental truth at the test's operating point (d-current bias).",
        "",
    ]
    for rig in rigs:
        path = resolve(rig, "rig")
        runs: list[tuple[int, CommissionResult, dict[str, float]]] = []
        for s in seeds:
            _p, res, errs = commission_once(path, s, out / f"commission-{Path(path).stem}-{s}.mcap")
            runs.append((s, res, errs))
        t = table(Path(path).stem, runs)
        echo(t + "\n")
        parts += [t, ""]
    text = "\n".join(parts)
    (out / "commission.md").write_text(text)
    echo(f"table {out / 'commission.md'}")
    return text
