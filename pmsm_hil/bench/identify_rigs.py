"""`pmsm-hil bench identify --rigs default,lab-typical [--commissioned]`: the identification run
on several rigs and seeds, one table per rig with the median and the worst error over the seeds
(docs/identification.md). With --commissioned each seed first commissions its rig
(`pmsm-hil commission`) and identifies with the commissioned motor file, as a drive would. The
rigs' and seeds' runs are trials on the sweep's Dask machinery (pmsm_hil.bench.trials)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.bench.trials import BenchInputError, Cluster, groups, key_text, run_trials

PARAMS = (("l_d_h", "L_d"), ("l_q_h", "L_q"), ("psi_f_wb", "psi_f"), ("r_s_ohm", "R"))
ESTIMATORS = ("rls", "nlms_adaline")


def _one(
    path: Path | str,
    rig_path: str,
    seed: int,
    out: Path,
    commissioned: bool,
    motor: Path | str | None = None,
) -> dict:
    from pmsm_hil.analysis.identification import identification_table
    from pmsm_hil.bench.identify import _run_profile
    from pmsm_hil.profiles import load_profile

    stem = Path(rig_path).stem
    if commissioned:
        from pmsm_hil.commission.sequence import commission_in_process

        log_c = out / f"commission-{stem}-{seed}.mcap"
        motor_c = out / f"motor-{stem}-{seed}.yaml"
        _prof, res = commission_in_process(motor, rig_path, seed, log_c, motor_c)
        if not res.ok:
            return {"failed": f"commissioning: {res.failure or res.run.stop_reason}"}
        motor = motor_c
    profile = load_profile(path, rig_override=rig_path, motor_override=motor)
    log = out / f"identify-{stem}-{seed}.mcap"
    _, result = _run_profile(profile, log, seed)
    if result.faults or result.error:
        return {"failed": f"run: {result.error or result.faults}"}
    drift = [s for s in profile.segments if s.plant is not None]
    t1 = drift[0].t_start_s if drift else profile.total_duration_s
    tab = identification_table(log, 0.0, t1)
    cells = {}
    for e in ESTIMATORS:
        for q, _ in PARAMS:
            c = tab.cell(e, q)
            if c is not None:
                cells[(e, q)] = (c.error_rel, c.conv_s)
    drift_s: dict[str, float | None] = {}
    if drift:  # after the plant's step: time until NLMS-Adaline stays within 2 % of the new truth
        d = identification_table(log, drift[0].t_start_s, drift[0].t_end_s)
        for q in ("r_s_ohm", "psi_f_wb"):
            c = d.cell("nlms_adaline", q)
            drift_s[q] = c.conv_s if c is not None else None
    return {"cells": cells, "drift_s": drift_s}


def identify_trial(task: dict[str, Any]) -> dict[str, Any]:
    """One rig and seed of the table (a Dask task): `_one` with its cells as JSON-able rows."""
    r = _one(
        task["profile"],
        task["rig"],
        task["seed"],
        Path(task["out"]),
        task["commissioned"],
        task["motor"],
    )
    if "cells" in r:
        r["cells"] = [[e, q, err, conv] for (e, q), (err, conv) in r["cells"].items()]
    return r


def _trials(
    path: Path | str,
    rig_paths: list[str],
    seeds: list[int],
    out: Path,
    commissioned: bool,
    motor: Path | str | None,
    cluster: Cluster | None,
) -> list[dict]:
    """`_one` for every rig and seed (rig-major), run as trials; cells keyed by (estimator,
    quantity) again, a trial that could not be made as {"failed": why}."""
    tasks = []
    for rp in rig_paths:
        stem = Path(rp).stem
        for s in seeds:
            logs = [str((out / f"identify-{stem}-{s}.mcap").resolve())]
            if commissioned:
                logs.append(str((out / f"commission-{stem}-{s}.mcap").resolve()))
            tasks.append(
                {
                    "profile": str(Path(path).resolve()),
                    "rig": str(Path(rp).resolve()),
                    "seed": int(s),
                    "out": str(out.resolve()),
                    "commissioned": commissioned,
                    "motor": str(Path(motor).resolve()) if motor else None,
                    "logs": logs,
                    "texts": [key_text(path), key_text(rp), key_text(motor)],  # in the key only
                }
            )
    results = run_trials(identify_trial, tasks, out, cluster, name="identify-rigs")
    for r in results:
        if "error" in r:
            r["failed"] = r.pop("error")
        if "cells" in r:
            r["cells"] = {(e, q): (err, conv) for e, q, err, conv in r["cells"]}
    return results


def _fmt(vals: list[float]) -> str:
    a = np.abs(np.array(vals)) * 100.0
    return f"{np.median(a):.2f} % / {a.max():.2f} %"


def identify_rigs(
    path: Path | str,
    rigs: list[str],
    seeds: list[int],
    out: Path,
    commissioned: bool = False,
    motor: Path | str | None = None,
    echo: Callable[[str], None] = print,
    cluster: Cluster | None = None,
) -> str:
    from pmsm_hil.bench.identify import check_profile
    from pmsm_hil.profiles.shipped import resolve

    if not seeds:
        raise BenchInputError("no seeds given")
    check_profile(str(path), motor=str(motor) if motor else None)
    rig_paths = [resolve(rig, "rig") for rig in rigs]  # a name that finds no file: before `out`
    out.mkdir(parents=True, exist_ok=True)
    what = "after commissioning" if commissioned else "with the motor file's values"
    parts = [
        f"# Online identification on several rigs, {what}",
        f"seeds {', '.join(map(str, seeds))}; |error| against /sim/truth before the drift step "
        f"(L_d, L_q: the apparent, secant inductances at the operating point; "
        f"docs/identification.md), median / worst over the seeds; convergence time median / worst",
        "",
    ]
    every = _trials(path, rig_paths, seeds, out, commissioned, motor, cluster)
    for rp, part in zip(rig_paths, groups(every, len(seeds)), strict=True):
        results = list(zip(seeds, part, strict=True))
        ok = [r["cells"] for _s, r in results if "cells" in r]
        lines = [
            f"### rig {Path(rp).stem}: {len(ok)} of {len(seeds)} seeds ran",
            "",
            "| estimator | " + " | ".join(n for _q, n in PARAMS) + " | t_conv L_d/L_q/psi_f s |",
            "|---|" + "---|" * (len(PARAMS) + 1),
        ]
        for e in ESTIMATORS:
            row = [e]
            for q, _n in PARAMS:
                vals = [c[(e, q)][0] for c in ok if (e, q) in c]
                row.append(_fmt(vals) if vals else "-")
            conv = []
            for q in ("l_d_h", "l_q_h", "psi_f_wb"):
                ts = [c[(e, q)][1] for c in ok if (e, q) in c]
                never = sum(1 for t in ts if t is None)
                tv = [t for t in ts if t is not None]
                conv.append(
                    (f"{np.median(tv):.2f}/{max(tv):.2f}" if tv else "never")
                    + (f" ({never} never)" if never and tv else "")
                )
            lines.append("| " + " | ".join(row) + " | " + "; ".join(conv) + " |")
        drifts = [r["drift_s"] for _s, r in results if r.get("drift_s")]
        if drifts:
            dl = []
            for q, n in (("r_s_ohm", "R"), ("psi_f_wb", "psi_f")):
                ts = [d[q] for d in drifts]
                tv = [t for t in ts if t is not None]
                never = len(ts) - len(tv)
                text = f"{n} {np.median(tv):.2f} / {max(tv):.2f} s" if tv else f"{n} never"
                if tv and never:
                    text += f" ({never} of {len(ts)} never)"
                dl.append(text)
            lines.append(
                "\nNLMS-Adaline after the drift step (time until it stays within 2 % of the new "
                "truth, median / worst): " + "; ".join(dl)
            )
        for s, r in results:
            if "failed" in r:
                lines.append(f"\nseed {s}: {r['failed']}")
        t = "\n".join(lines)
        echo(t + "\n")
        parts += [t, ""]
    text = "\n".join(parts)
    name = "identify-rigs-commissioned.md" if commissioned else "identify-rigs.md"
    (out / name).write_text(text)
    echo(f"table {out / name}")
    return text


def per_effect_commissioned(
    path: Path | str,
    seeds: list[int],
    out: Path,
    echo: Callable[[str], None] = print,
    cluster: Cluster | None = None,
) -> str:
    """What each rig effect still costs after commissioning: NLMS-Adaline's |error| (median /
    worst over the seeds) on the ideal rig, each effect alone, default and lab-typical, each seed
    commissioned first."""
    from pmsm_hil.bench.identify import check_profile
    from pmsm_hil.profiles.shipped import shipped_root

    if not seeds:
        raise BenchInputError("no seeds given")
    check_profile(str(path))
    rigs_dir = shipped_root() / "rigs"
    rigs = [
        "ideal",
        *sorted(f.stem for f in rigs_dir.glob("effect-*.yaml")),
        "default",
        "lab-typical",
    ]
    out.mkdir(parents=True, exist_ok=True)
    head = "| rig | " + " | ".join(n for _q, n in PARAMS) + " |"
    lines = [
        "# NLMS-Adaline after commissioning, per rig effect",
        f"seeds {', '.join(map(str, seeds))}: |error| median / worst before the drift step",
        "",
        head,
        "|---|" + "---|" * len(PARAMS),
    ]
    echo("\n".join(lines))
    every = _trials(
        path, [str(rigs_dir / f"{r}.yaml") for r in rigs], seeds, out, True, None, cluster
    )
    for r, res in zip(rigs, groups(every, len(seeds)), strict=True):
        ok = [x["cells"] for x in res if "cells" in x]
        cells = []
        for q, _n in PARAMS:
            vals = [c[("nlms_adaline", q)][0] for c in ok if ("nlms_adaline", q) in c]
            cells.append(_fmt(vals) if vals else "-")
        failed = [x["failed"] for x in res if "failed" in x]
        row = f"| {r} | " + " | ".join(cells) + " |" + (f" {failed[0]}" if failed else "")
        lines.append(row)
        echo(row)
    text = "\n".join(lines)
    (out / "per-effect-commissioned.md").write_text(text + "\n")
    return text
