"""`pmsm-hil bench commission`: the commissioning sequence on the emulator over several rigs and
seeds, each result scored against the plant (pmsm_hil.commission.score); one table per rig with
the median and the worst error over the seeds beside the target (docs/commissioning.md). The rigs'
and seeds' runs are trials on the sweep's Dask machinery (pmsm_hil.bench.trials)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pmsm_hil.bench.trials import BenchInputError, Cluster, groups, key_text, run_trials

if TYPE_CHECKING:
    from pmsm_hil.commission.sequence import CommissionResult
    from pmsm_hil.profiles import Profile

# quantity -> (label, unit, scale for printing, target on |error|)
TARGETS = {
    "offset_a_a": ("sensor offset a", "mA", 1e3, 0.005),
    "offset_b_a": ("sensor offset b", "mA", 1e3, 0.005),
    "offset_c_a": ("sensor offset c", "mA", 1e3, 0.005),
    "gain_a": ("sensor gain error a", "%", 100.0, 0.005),
    "gain_b": ("sensor gain error b", "%", 100.0, 0.005),
    "gain_c": ("sensor gain error c", "%", 100.0, 0.005),
    "enc_offset_deg": ("encoder offset", "deg el.", 1.0, 0.2),
    "plateau_rel": ("dead-time plateau", "%", 100.0, 0.05),
    "dead_time_rel": ("dead time alone", "%", 100.0, 0.05),
    "v_drop_v": ("device drop", "V", 1.0, 0.25),
    "r_rel": ("R (vs hot truth)", "%", 100.0, 0.02),
    "l_d_rel": ("L_d at standstill", "%", 100.0, 0.05),
    "l_q_rel": ("L_q at standstill", "%", 100.0, 0.05),
    "psi_f_rel": ("psi_f (spin)", "%", 100.0, 0.01),
}


def commission_once(
    rig_path: str | None, seed: int, log: Path, motor_path: Path | str | None = None
) -> tuple[Profile, CommissionResult, dict[str, float]]:
    """One in-process commissioning run: (result, errors against the plant)."""
    from pmsm_hil.commission.score import commission_errors
    from pmsm_hil.commission.sequence import commission_in_process

    profile, res = commission_in_process(motor_path, rig_path, seed, log)
    errs: dict[str, float] = (
        commission_errors(log, res.quantities, profile.rig, profile.control.ts_s) if res.ok else {}
    )
    return profile, res, errs


def commission_trial(task: dict[str, Any]) -> dict[str, Any]:
    """One rig and seed (a Dask task): whether it completed, why not, its errors."""
    _p, res, errs = commission_once(task["rig"], task["seed"], Path(task["log"]), task.get("motor"))
    return {"ok": bool(res.ok), "failure": str(res.failure or res.run.stop_reason), "errors": errs}


def table(rig_name: str, runs: list[tuple[int, dict[str, Any]]]) -> str:
    """Markdown: per quantity, target, median and worst |error|, seeds within the target. A run
    is (seed, commission_trial's result)."""
    n = len(runs)
    ok = [r for _s, r in runs if r.get("ok")]
    lines = [
        f"### rig {rig_name}: {len(ok)} of {n} seeds completed",
        "",
        "| quantity | target | median abs error | worst abs error | within target |",
        "|---|---|---|---|---|",
    ]
    for key, (label, unit, k, target) in TARGETS.items():
        vals = np.array([abs(r["errors"][key]) for r in ok if key in r["errors"]])
        if vals.size == 0:
            continue
        within = int(np.sum(vals <= target))
        lines.append(
            f"| {label} | {target * k:g} {unit} | {np.median(vals) * k:.3g} {unit} | "
            f"{vals.max() * k:.3g} {unit} | {within}/{vals.size} |"
        )
    for s, r in runs:
        if not r.get("ok"):
            lines.append(f"\nseed {s}: {r.get('failure') or r.get('error')}")
    return "\n".join(lines)


def bench_commission(
    rigs: list[str],
    seeds: list[int],
    out: Path,
    echo: Callable[[str], None] = print,
    cluster: Cluster | None = None,
    motor: str | None = None,
) -> str:
    """Runs every (rig, seed) as trials, prints and writes the tables (out/commission.md), on
    ``motor`` (a file or shipped name; None: paper A's motor, as `pmsm-hil commission`). A rig or
    motor that names no file (ProfileError) or no seeds (BenchInputError) is refused before
    ``out`` is made."""
    from pmsm_hil.profiles.shipped import resolve

    if not seeds:
        raise BenchInputError("no seeds given")
    paths = [resolve(rig, "rig") for rig in rigs]
    motor_path = str(Path(resolve(motor, "motor")).resolve()) if motor else None
    out.mkdir(parents=True, exist_ok=True)
    parts = [
        f"# Commissioning on the emulator, seeds {seeds[0]}..{seeds[-1]} ({len(seeds)} seeds), "
        f"motor {Path(motor_path).stem if motor_path else 'paper-a-ipmsm'}",
        "",
        "Errors against the plant: sensor offsets, gain errors (against each channel's gain over "
        "the three's mean) and the encoder offset absolute, the rest "
        "relative; R against the winding's temperature-dependent truth during the R step, L_d "
        "and L_q against the incremental truth at the test's operating point (d-current bias).",
        "",
    ]
    tasks = [
        {
            "rig": str(Path(p).resolve()),
            "seed": int(s),
            "motor": motor_path,
            "log": str((out / f"commission-{Path(p).stem}-{s}.mcap").resolve()),
            "text": key_text(p),  # in the key only
            "motor_text": key_text(motor_path),
        }
        for p in paths
        for s in seeds
    ]
    every = run_trials(commission_trial, tasks, out, cluster, name="commission")
    for path, part in zip(paths, groups(every, len(seeds)), strict=True):
        runs = list(zip(seeds, part, strict=True))
        t = table(Path(path).stem, runs)
        echo(t + "\n")
        parts += [t, ""]
    text = "\n".join(parts)
    (out / "commission.md").write_text(text)
    echo(f"table {out / 'commission.md'}")
    return text
