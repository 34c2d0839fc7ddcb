"""`pmsm-hil bench sensorless`: runs the scenarios (bench/sensorless.py) per rig and seed, reduces
each figure to its median and worst over the seeds, and writes the table (markdown, echoed as
text) and the PNG plots of angle error and speed. The runs (profiles x rigs x seeds) are trials on
the sweep's Dask machinery (pmsm_hil.bench.trials); the figures are computed here from their logs."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from pmsm_hil.bench.sensorless import (
    DEFAULT_RIGS,
    DEFAULT_SEEDS,
    RunData,
    Scenario,
    read_run,
    rig_for,
    scenario_figures,
    select,
)
from pmsm_hil.bench.trials import BenchInputError, Cluster, groups

# figure key -> (column title, format, how "worst" is taken)
STEADY_COLS = (
    ("angle_truth_mean_rad", "angle mean vs plant rad", "{:+.4f}", "abs"),
    ("angle_mean_rad", "angle mean rad", "{:+.4f}", "abs"),
    ("angle_rms_rad", "angle RMS rad", "{:.4f}", "max"),
    ("speed_est_err_rpm", "speed est. err r/min", "{:+.2f}", "abs"),
    ("speed_est_err_max_rpm", "worst 10 ms speed est. err", "{:.2f}", "max"),
    ("speed_track_rpm", "speed tracking r/min", "{:+.2f}", "abs"),
)
TRANSIENT_COLS = (
    ("angle_max_rad", "max angle err rad", "{:.4f}", "max"),
    ("recovery_s", "recovery s", "{:.3f}", "max"),
)


def _reduce(values: list[float], how: str) -> tuple[float, float]:
    v = np.asarray([x for x in values if x is not None], float)
    if v.size == 0:
        return math.nan, math.nan
    worst = v[np.argmax(np.abs(v))] if how == "abs" else float(np.max(v))
    return float(np.median(v)), float(worst)


def _cell(values: list[float], fmt: str, how: str) -> str:
    med, worst = _reduce(values, how)
    return f"{fmt.format(med)} / {fmt.format(worst)}"


def scenario_table(sc: Scenario, per_seed: list[dict]) -> list[str]:
    """Markdown lines for one scenario on one rig: median / worst over the seeds."""
    lines = [
        "| window | " + " | ".join(c[1] for c in STEADY_COLS) + " |",
        "|---|" + "---|" * len(STEADY_COLS),
    ]
    for w in sc.steady:
        cells = [
            _cell([f[w.label].get(k) for f in per_seed], fmt, how) for k, _, fmt, how in STEADY_COLS
        ]
        lines.append(f"| {w.label} | " + " | ".join(cells) + " |")
    if sc.transients:
        lines += [
            "",
            "| transient | " + " | ".join(c[1] for c in TRANSIENT_COLS) + " |",
            "|---|" + "---|" * len(TRANSIENT_COLS),
        ]
    for tw in sc.transients:
        cells = [
            _cell([f[tw.label].get(k) for f in per_seed], fmt, how)
            for k, _, fmt, how in TRANSIENT_COLS
        ]
        lines.append(f"| {tw.label} | " + " | ".join(cells) + " |")
    kept = sum(1 for f in per_seed if f["lock_kept"])
    lines.append("")
    lines.append(f"lock kept in {kept} of {len(per_seed)} runs")
    faults = sorted({f["faults"] for f in per_seed if f["faults"]})
    if faults:
        lines.append("faults: " + "; ".join(faults))
    return lines


def targets_met(sc: Scenario, per_seed: list[dict]) -> list[str]:
    """The scenario's targets against the worst seed."""
    t = sc.targets
    out = []
    if "steady_rad" in t:
        worst = max(
            max(abs(f[w.label].get("angle_mean_rad", math.nan)), f[w.label].get("angle_rms_rad", 0))
            for f in per_seed
            for w in sc.steady
        )
        out.append(
            f"steady angle error <= {t['steady_rad']:g} rad: worst {worst:.4f} "
            f"({'met' if worst <= t['steady_rad'] else 'MISSED'})"
        )
    if "steady_rms_rad" in t:  # paper A's form: RMS about zero (the mean is in it)
        worst = max(f[w.label].get("angle_rms_rad", math.nan) for f in per_seed for w in sc.steady)
        out.append(
            f"steady angle error <= {t['steady_rms_rad']:g} rad RMS: worst {worst:.4f} "
            f"({'met' if worst <= t['steady_rms_rad'] else 'MISSED'})"
        )
    if "transient_rad" in t:
        worst = max(
            f[w.label].get("angle_max_rad", math.nan) for f in per_seed for w in sc.transients
        )
        out.append(
            f"transient angle error <= {t['transient_rad']:g} rad: worst {worst:.4f} "
            f"({'met' if worst <= t['transient_rad'] else 'MISSED'})"
        )
    if "speed_rpm" in t:
        worst = max(
            abs(f[w.label].get("speed_est_err_rpm", math.nan)) for f in per_seed for w in sc.steady
        )
        out.append(
            f"steady speed-estimate error <= +-{t['speed_rpm']:g} r/min: worst {worst:.2f} "
            f"({'met' if worst <= t['speed_rpm'] else 'MISSED'})"
        )
    if "speed_10ms_rpm" in t:  # the estimate as the speed loop sees it, 10 ms at a time
        worst = max(
            f[w.label].get("speed_est_err_max_rpm", math.nan) for f in per_seed for w in sc.steady
        )
        out.append(
            f"speed-estimate error of every 10 ms mean <= +-{t['speed_10ms_rpm']:g} r/min: worst "
            f"{worst:.2f} ({'met' if worst <= t['speed_10ms_rpm'] else 'MISSED'})"
        )
    return out


def plot_run(run: RunData, title: str, png: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    ax1.plot(run.t, run.theta_err, lw=0.6, color="C3")
    ax1.set_ylabel("angle error rad\n(estimate - encoder)")
    ax1.grid(alpha=0.3)
    lim = max(0.05, min(0.5, 1.2 * float(np.max(np.abs(run.theta_err[run.t > 0.1]), initial=0))))
    ax1.set_ylim(-lim, lim)
    ax2.plot(run.t, run.speed_ref, lw=0.8, color="0.5", label="reference")
    ax2.plot(run.t, run.speed, lw=0.8, color="C0", label="encoder")
    ax2.plot(run.t, run.speed_est, lw=0.6, color="C2", label="estimate")
    ax2.set_ylabel("speed r/min")
    ax2.set_xlabel("t s")
    ax2.legend(loc="lower right")
    ax2.grid(alpha=0.3)
    for t0, _ in run.segments.values():
        for ax in (ax1, ax2):
            ax.axvline(t0, color="0.8", lw=0.5)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def sensorless(
    out: Path,
    seeds: Sequence[int] = DEFAULT_SEEDS,
    rigs: Sequence[str] = DEFAULT_RIGS,
    only: str | None = None,
    echo: Callable[[str], None] = print,
    cluster: Cluster | None = None,
) -> dict:
    """Run every scenario (or those whose profile or name contains `only`; none is a
    BenchInputError) on each rig and seed; write out/sensorless.md and the plots; return
    {(scenario, rig): [figures per seed]}."""
    from pmsm_hil.bench.identify import BenchError, _job, run_jobs
    from pmsm_hil.profiles import load_profile
    from pmsm_hil.profiles.shipped import shipped_file

    chosen = select(only)  # none: refused before `out` is made
    if not seeds or not rigs:
        raise BenchInputError(f"no {'seeds' if not seeds else 'rigs'} given")
    profiles = sorted({s.profile for s in chosen})
    results: dict = {}
    md = ["# Sensorless benchmark", "", f"seeds {', '.join(map(str, seeds))}; median / worst", ""]
    cases = []  # (profile name, its path, rig name, rig path, note), as the table goes
    for prof in profiles:
        ppath = shipped_file(prof)
        for rig in rigs:  # a rig that names no file: ProfileError, before `out` is made
            cases.append((prof, ppath, rig, *rig_for(ppath, rig, out)))
    out.mkdir(parents=True, exist_ok=True)
    jobs = [
        _job(ppath, out / f"{Path(prof).stem}-{rig}-seed{seed}.mcap", seed, rig=rig_path)
        for prof, ppath, rig, rig_path, _note in cases
        for seed in seeds
    ]
    done = run_jobs(jobs, out, cluster)
    for (prof, ppath, rig, rig_path, note), case_jobs, case_done in zip(
        cases, groups(jobs, len(seeds)), groups(done, len(seeds)), strict=True
    ):
        if note:
            echo("note: " + note)
            md += [f"note: {note}", ""]
        profile = load_profile(ppath, rig_override=rig_path)
        runs = []
        for job, res in zip(case_jobs, case_done, strict=True):
            if res.get("error"):
                raise BenchError(f"the run failed ({res['error']}); log {job['log']}")
            runs.append(read_run(Path(job["log"]), profile))
        plot_run(runs[0], f"{prof} on {rig}, seed {seeds[0]}", out / f"{Path(prof).stem}-{rig}.png")
        for sc in [s for s in chosen if s.profile == prof]:
            per_seed = [scenario_figures(sc, r) for r in runs]
            results[(sc.name, rig)] = per_seed
            lines = [
                f"## {sc.name} - rig {rig}",
                "",
                f"each cell: median / worst over seeds {', '.join(map(str, seeds))}",
                "",
                *scenario_table(sc, per_seed),
            ]
            if sc.paper:
                lines += ["", f"paper: {sc.paper}"]
            if rig == "default":
                lines += [""] + [f"target: {x}" for x in targets_met(sc, per_seed)]
            md += [*lines, ""]
            echo("\n".join(lines) + "\n")
    (out / "sensorless.md").write_text("\n".join(md) + "\n")
    echo(f"written: {out / 'sensorless.md'} and the plots in {out}")
    return results
