"""Runs the firmware's commissioning sequence on a device and collects its results
(docs/commissioning.md). The sequence is a profile of one `commission` segment
(profiles/commission.yaml) with the motor (and, on the emulator, the rig) of the caller; the
firmware runs every step, the host only configures, logs and reads the results."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pmsm_hil.commission.steps import Measured, failure_text, step_quantities
from pmsm_hil.profiles import Profile, load_profile
from pmsm_hil.profiles._base import default_file
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import Observer, RunOptions, RunResult, run_profile

STEPS = tuple(gen.ENUMS["commission_step"])  # firmware order


@dataclass
class CommissionResult:
    run: RunResult
    rows: list[dict[str, Any]] = field(default_factory=list)  # /pmsm/commission rows in order
    quantities: dict[str, Measured] = field(default_factory=dict)
    failure: str = ""  # readable reason when a step failed
    failed_step: str = ""
    failed_why: str = ""

    @property
    def ok(self) -> bool:
        return (
            not self.failure
            and not self.run.error
            and not self.run.interrupted
            and self.run.stop_reason == "profile end"
            and not self.run.faults
        )


def commission_profile(
    motor_path: Path | str | None = None,
    rig_path: Path | str | None = None,
    profile_path: Path | str | None = None,
) -> Profile:
    """The commissioning profile with the caller's motor and rig files."""
    return load_profile(
        profile_path or default_file("commission.yaml"),
        rig_override=rig_path,
        motor_override=motor_path,
    )


def commission_request(
    profile: Profile,
    steps: Iterable[str] | None = None,
    i_test_a: float | None = None,
    spin_rpm: float | None = None,
) -> tuple[str, dict[str, float | int]]:
    """The config_commission message: which steps (names, default all), the test current and the
    spin speed (defaults: half the motor's current and speed limits)."""
    m = profile.motor
    names = list(steps) if steps else list(STEPS)
    unknown = [s for s in names if s not in STEPS]
    if unknown:
        raise ValueError(f"unknown commissioning step(s) {', '.join(unknown)}: {', '.join(STEPS)}")
    mask = 0
    for s in names:
        mask |= 1 << gen.ENUMS["commission_step"][s]
    return "config_commission", dict(
        steps=mask,
        i_test_a=float(i_test_a if i_test_a is not None else 0.5 * m.i_max_a),
        spin_rpm=float(spin_rpm if spin_rpm is not None else 0.5 * m.speed_max_rpm),
    )


def run_commission(
    profile: Profile,
    session: Session,
    log_path: Path,
    options: RunOptions | None = None,
    observer: Observer | None = None,
    **request: Any,
) -> CommissionResult:
    """Run the sequence on the device behind `session`; the motor stops safely whatever happens
    (the runner's guarantees) and the log is left readable."""
    options = options or RunOptions()
    options.requests = [*list(options.requests), commission_request(profile, **request)]
    options.capture = False
    run = run_profile(profile, session, log_path, options, observer)
    out = CommissionResult(run=run)
    for _t, row in run.live.commission:
        out.rows.append(row)
        if row["status"] == "ok":
            out.quantities.update(step_quantities(row))
        else:
            out.failed_step, out.failed_why = row["step"], row["status"]
            out.failure = failure_text(row["step"], row["status"])
    if not out.failure and run.stop_reason == "commission failed":
        out.failure = "commissioning stopped (its result frame was lost; see the log's events)"
    return out


def commission_in_process(
    motor_path: Path | str | None,
    rig_path: Path | str | None,
    seed: int,
    log: Path,
    motor_out: Path | None = None,
) -> tuple[Profile, CommissionResult]:
    """One commissioning on the in-process emulator (as `pmsm-hil commission --motor M --rig R
    --seed S`): the profile it ran and its result; with ``motor_out``, the commissioned motor
    file is written there when the sequence completed."""
    from pmsm_hil.commission.motor_file import commissioned_motor_yaml
    from pmsm_hil.device import DeviceSpec, open_device

    profile = commission_profile(motor_path, rig_path)
    link = open_device(DeviceSpec(in_process=True, seed=seed), profile)
    try:
        res = run_commission(profile, Session(link), log, RunOptions(seed=seed))
    finally:
        link.close()
    if motor_out is not None and res.ok:
        text = commissioned_motor_yaml(
            profile.motor,
            res.quantities,
            profile.control.ts_s,
            "emulator",
            str(log),
            out_dir=str(Path(motor_out).parent),
        )
        Path(motor_out).write_text(text, encoding="utf-8")
    return profile, res
