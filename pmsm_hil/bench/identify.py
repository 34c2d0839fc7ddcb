"""The identification benchmark (`pmsm-hil bench identify`): paper A's identification profile on the
emulator in this process, the Table-2 figures beside the paper's, the mismatch benchmark and the
per-effect table. Results are written to a folder and echoed as text.

The benchmark's runs go through the sweep's Dask machinery (pmsm_hil.bench.trials; docs/sweep.md):
one run in this process, several (the mismatch cases, the rigs of the per-effect table; the rigs
and seeds of `--rigs` in bench/identify_rigs.py) as tasks on a local cluster or the scheduler
given, each writing its log into the output folder; a journal there (bench.jsonl, keyed by the
run's profile and rig texts, seed and log) lets an interrupted benchmark skip the runs whose logs
are already written. The figures are computed here from the
logs, whichever process ran them."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.bench.trials import BenchInputError, Cluster, key_text, run_trials
from pmsm_hil.device import DeviceSpec, open_device

if TYPE_CHECKING:
    from pmsm_hil.profiles import Profile


class BenchError(Exception):
    """A benchmark run failed (the message names the run and its log)."""


def default_profile() -> str:
    from pmsm_hil.profiles.shipped import shipped_file

    return shipped_file("paper-a-identify.yaml")


def identifying(profile: Profile) -> Profile:
    """``profile``, refused with BenchInputError when it does not identify (control.identify is
    false): every part of the benchmark reads its estimators' parameters, so it would only give
    an empty table."""
    if not profile.control.identify:
        raise BenchInputError(
            f"profile {profile.name} does not identify (its control.identify is false), so there "
            "is nothing to tabulate; give a profile with control.identify: true (the default, "
            "paper-a-identify, has it)"
        )
    return profile


def check_profile(path: str, rig: str | None = None, motor: str | None = None) -> Profile:
    """The benchmark's profile loaded as its runs load it: ProfileError when it is bad,
    BenchInputError when it does not identify (`identifying`); before anything runs."""
    from pmsm_hil.profiles import load_profile

    return identifying(load_profile(path, rig_override=rig, motor_override=motor))


def identify(
    path: str,
    out: Path,
    seed: int = 1,
    rig: str | None = None,
    until: float | None = None,
    echo: Callable[[str], None] = print,
    motor: str | None = None,
) -> None:
    """The Table-2 run: identification table (markdown and text), convergence plot, drift step."""
    from pmsm_hil.analysis.identification import (
        convergence_plot,
        identification_table,
        markdown_table,
        text_table,
    )
    from pmsm_hil.profiles import load_profile

    profile = identifying(load_profile(path, rig_override=rig, motor_override=motor))
    out.mkdir(parents=True, exist_ok=True)
    log = out / "identify.mcap"
    _, result = _run_profile(profile, log, seed)
    if result.faults or result.error:
        raise BenchError(f"the run failed ({result.error or result.faults}); log {log}")
    t1 = until
    drift = [s for s in profile.segments if s.plant is not None]
    if t1 is None:  # before the first drift step
        t1 = drift[0].t_start_s if drift else profile.total_duration_s
    effects = ", ".join(profile.rig.enabled_effects)
    echo(
        f"bench identify: {profile.name} on the emulator (motor {profile.motor.name}, rig "
        f"{profile.rig.name}: {effects}; seed {seed}); estimators from zero weights"
    )
    if (
        profile.control.dead_time_comp
        and profile.motor.dead_time_s
        and not profile.rig.enabled("dead_time")
    ):
        echo(
            f"note: the firmware compensates the motor file's {profile.motor.dead_time_s * 1e6:g} us dead time, "
            f"which rig {profile.rig.name} does not have: the voltages it assumes are wrong by that much"
        )
    table = identification_table(log, 0.0, t1)
    echo(text_table(table))
    md = out / "identify.md"
    md.write_text(
        f"# Online identification, {profile.name} (t <= {t1:g} s)\n\n"
        + markdown_table(table)
        + "\n"
    )
    png = convergence_plot(log, out / "identify.png")
    if drift:
        d = drift[0]
        assert d.plant is not None  # drift holds only the segments with a plant step
        dt = identification_table(log, d.t_start_s, d.t_end_s)
        echo(
            f"\ndrift step at t = {d.t_start_s:g} s (R x {d.plant.r_s_scale:g}, psi_f x "
            f"{d.plant.psi_f_scale:g}); convergence times from the step:"
        )
        for c in dt.cells:
            c.conv_s = (
                None if c.conv_s is None else c.conv_s + (c.t_first_s or d.t_start_s) - d.t_start_s
            )
        echo(text_table(dt, with_paper=False))
        md.write_text(
            md.read_text()
            + f"\n## Drift step at {d.t_start_s:g} s\n\n"
            + markdown_table(dt, False)
            + "\n"
        )
    echo(f"\nlog {log}\nplot {png}\ntable {md}")


def bench_run(task: dict) -> dict:
    """One benchmark run (a Dask task): the profile at task["profile"] (rig task["rig"] or its own)
    with task["seed"] on the in-process emulator, logged to task["log"]."""
    _, res = _run(task["profile"], Path(task["log"]), task["seed"], rig=task["rig"])
    return {"faults": int(res.faults or 0), "error": str(res.error or "")}


def _job(profile_path, log: Path, seed: int, rig=None) -> dict:
    return {
        "profile": str(Path(profile_path).resolve()),
        "rig": str(Path(rig).resolve()) if rig else None,
        "seed": int(seed),
        "log": str(Path(log).resolve()),
        "texts": [
            key_text(profile_path),
            key_text(rig),
        ],  # in the key only: a changed file runs again
    }


def run_jobs(jobs: list[dict], out: Path, cluster: Cluster | None = None) -> list[dict]:
    """The runs of ``jobs`` (see _job): one in this process, several on Dask; results in order."""
    return run_trials(bench_run, jobs, out, cluster)


def _run_profile(profile, log: Path, seed: int):
    from pmsm_hil.protocol.session import Session
    from pmsm_hil.runner import RunOptions, run_profile

    link = open_device(DeviceSpec(in_process=True, seed=seed), profile)
    try:
        return profile, run_profile(profile, Session(link), log, RunOptions(seed=seed))
    finally:
        link.close()


def _run(profile_path, log: Path, seed: int, rig=None):
    from pmsm_hil.profiles import load_profile

    return _run_profile(load_profile(str(profile_path), rig_override=rig), log, seed)


# ------------------------------------------------------------------------------- variants


def _variant(
    path: Path | str,
    out: Path,
    name: str,
    control: dict[str, Any] | None = None,
    segments: list[str] | None = None,
) -> Path:
    """A copy of the profile at `path` (motor and rig paths made absolute) with control fields
    replaced or added and, optionally, other segments; written to out/NAME.yaml."""
    import yaml

    src = Path(path).resolve()
    data = yaml.safe_load(src.read_text())
    for key in ("motor", "rig"):
        if isinstance(data.get(key), str) and not Path(data[key]).is_absolute():
            data[key] = str((src.parent / data[key]).resolve())
    data["name"] = f"{data.get('name', 'profile')}-{name}"
    data.setdefault("control", {}).update(control or {})
    if segments is not None:
        data["segments"] = [yaml.safe_load(t) for t in segments]
    p = out / f"{name}.yaml"
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


# ------------------------------------------------------------------------------- mismatch

MISMATCH_SCALE = 1.5  # "50 % off": L_d, L_q, psi_f of the predictor x 1.5
MISMATCH_WINDOW = (3.0, 4.0)  # device time evaluated: 1000 r/min, 5 N m, steady


def mismatch(
    path: Path | str,
    out: Path,
    seed: int = 1,
    echo: Callable[[str], None] = print,
    cluster: Cluster | None = None,
) -> None:
    """i_d/i_q tracking-error RMS at 1000 r/min under load: true parameters, predictor frozen 50 %
    off, NLMS-Adaline feeding the predictor (from the same 50 % off start)."""
    import numpy as np

    from pmsm_hil.log.reader import read_log

    check_profile(str(path))
    out.mkdir(parents=True, exist_ok=True)
    segs = [
        '{name: "R injection", kind: identify_r, duration_s: 0.5, speed_rpm: 0, inject_a: 12.0}',
        '{name: "spin up, load", duration_s: 1.0, speed_rpm: 1000, ramp_rpm_s: 2000, load_nm: 5.0, inject_a: 2.0, inject_hz: 10}',
        '{name: "1000 r/min, load", duration_s: 2.5, speed_rpm: 1000, load_nm: 5.0, inject_a: 2.0, inject_hz: 10}',
        '{name: "stop", duration_s: 0.8, speed_rpm: 0, ramp_rpm_s: 2000, load_nm: 0}',
    ]
    off = {
        "l_d_h": MISMATCH_SCALE,
        "l_q_h": MISMATCH_SCALE,
        "psi_f_wb": MISMATCH_SCALE,
        "r_s_ohm": 1.0,
    }
    cases: list[tuple[str, dict[str, Any]]] = [
        ("true parameters", {"predictor": "nominal"}),
        (
            f"frozen x{MISMATCH_SCALE:g} (L_d, L_q, psi_f)",
            {"predictor": "nominal", "predictor_scale": off},
        ),
        ("NLMS-Adaline feeds it", {"predictor": "nlms_adaline", "predictor_scale": off}),
    ]
    rows = []
    jobs = [
        _job(_variant(path, out, f"mismatch-{i}", ctrl, segs), out / f"mismatch-{i}.mcap", seed)
        for i, (_, ctrl) in enumerate(cases)
    ]
    results = run_jobs(jobs, out, cluster)
    for (label, _), job, res in zip(cases, jobs, results, strict=False):
        log = Path(job["log"])
        if res.get("faults") or res.get("error"):
            raise BenchError(
                f"mismatch run {label!r} failed ({res.get('error') or res.get('faults')}); "
                f"log {log}"
            )
        tel = read_log(log).topic("/pmsm/telemetry")
        t = np.asarray(tel["t_s"], dtype=float)
        m = (t >= MISMATCH_WINDOW[0]) & (t < MISMATCH_WINDOW[1])
        ed = np.asarray(tel["i_d_ref_a"])[m] - np.asarray(tel["i_d_a"])[m]
        eq = np.asarray(tel["i_q_ref_a"])[m] - np.asarray(tel["i_q_a"])[m]
        rows.append(
            (
                label,
                float(np.sqrt(np.mean(ed**2))),
                float(np.sqrt(np.mean(eq**2))),
                float(np.sqrt(np.mean(ed**2 + eq**2))),
            )
        )
    ref = rows[0][3]
    lines = [
        "| predictor | i_d error RMS (A) | i_q error RMS (A) | |i| error RMS (A) | vs true |",
        "|---|---|---|---|---|",
    ]
    for label, d, q, tot in rows:
        lines.append(
            f"| {label} | {d:.3f} | {q:.3f} | {tot:.3f} | {100 * (tot / ref - 1):+.1f} % |"
        )
    md = "\n".join(lines)
    echo(
        f"\nmismatch: tracking error at 1000 r/min, 5 N m, t = {MISMATCH_WINDOW[0]:g}..{MISMATCH_WINDOW[1]:g} s "
        f"(telemetry samples: the sampled current at k, before the MPCC step)"
    )
    echo(md)
    (out / "mismatch.md").write_text(
        "# Mismatch: current tracking with the predictor's parameters\n\n" + md + "\n"
    )


# ------------------------------------------------------------------------------- per effect


def _fault_names(bits: int) -> str:
    from pmsm_hil.protocol import generated

    names = [n for n, b in generated.ENUMS["fault"].items() if bits & b]
    return "fault " + (", ".join(names) if names else f"0x{bits:x}")


def per_effect(
    path: Path | str,
    out: Path,
    seed: int = 1,
    echo: Callable[[str], None] = print,
    cluster: Cluster | None = None,
) -> None:
    """The identification run (without its drift step) on the ideal rig, each effect alone and the
    default rig: errors of RLS and NLMS-Adaline before the drift step, as a markdown table."""
    import yaml

    from pmsm_hil.analysis.identification import identification_table
    from pmsm_hil.profiles.shipped import shipped_root

    check_profile(str(path))
    rigs_dir = shipped_root() / "rigs"
    out.mkdir(parents=True, exist_ok=True)
    src = yaml.safe_load(Path(path).read_text())
    segs = [
        yaml.safe_dump(s, default_flow_style=True).strip()
        for s in src["segments"]
        if not s.get("plant")
    ]
    rigs = [
        "ideal",
        *sorted(f.stem for f in rigs_dir.glob("effect-*.yaml")),
        "default",
        "lab-typical",
    ]
    head = (
        "| rig | "
        + " | ".join(f"{e} {n}" for e in ("rls", "nlms") for n in ("L_d", "L_q", "psi_f", "R"))
        + " | nlms t_conv L_d/L_q/psi_f s |"
    )
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    echo(
        "\nper effect: identification (before any drift step) on each rig; error against /sim/truth"
    )
    echo(lines[0])
    echo(lines[1])
    from pmsm_hil.profiles import load_profile, load_rig

    jobs = []
    for r in rigs:
        # the firmware compensates the inverter it is told about: the motor file's dead time when the
        # rig has one (the rig's true one may differ: effect-dead-time, lab-typical), else none
        has_dt = "dead_time" in load_rig(rigs_dir / f"{r}.yaml").enabled_effects
        pr = _variant(
            path, out, f"per-effect-{'dt' if has_dt else 'nodt'}", {"dead_time_comp": has_dt}, segs
        )
        jobs.append(_job(pr, out / f"per-effect-{r}.mcap", seed, rig=rigs_dir / f"{r}.yaml"))
    results = run_jobs(jobs, out, cluster)
    for r, job, res in zip(rigs, jobs, results, strict=False):
        log = Path(job["log"])
        if res.get("faults") or res.get("error"):
            why = res.get("error") or _fault_names(res["faults"])
            row = f"| {r} | run failed: {why} |"
        else:
            prof = load_profile(job["profile"], rig_override=job["rig"])
            t1 = prof.segments[-1].t_start_s  # before the stop
            tab = identification_table(log, 0.0, t1)
            cells = []
            for e in ("rls", "nlms_adaline"):
                for q in ("l_d_h", "l_q_h", "psi_f_wb", "r_s_ohm"):
                    c = tab.cell(e, q)
                    cells.append("-" if c is None else f"{100 * c.error_rel:+.2f} %")
            conv = []
            for q in ("l_d_h", "l_q_h", "psi_f_wb"):
                c = tab.cell("nlms_adaline", q)
                conv.append("never" if c is None else c.conv_text(2))
            row = f"| {r} | " + " | ".join(cells) + " | " + " / ".join(conv) + " |"
        lines.append(row)
        echo(row)
    (out / "per-effect.md").write_text(
        "# Identification per rig effect\n\n" + "\n".join(lines) + "\n"
    )
