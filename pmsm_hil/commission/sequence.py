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
from pmsm_hil.control_design import encoder_counts
from pmsm_hil.files import write_text_whole
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


# A step that needs another's result in the same sequence (firmware/core/comm_*.c): r_s and psi_f
# add the measured inverter distortion to the applied voltage (comm_inv_dist); without the
# inverter step there is none (no nominal model to fall back on), and the unmodelled distortion
# (tens of volts at standstill) biases R and, unequally at the two spin speeds, psi_f.
STEP_NEEDS = {"r_s": ("inverter",), "psi_f": ("inverter",)}
# steps that drive the motor in the rotor frame: without `encoder` they take the rotor angle from
# the motor file's enc_offset_e_rad
ANGLE_STEPS = ("inverter", "r_s", "l_dq", "psi_f")


class RequestError(ValueError):
    """A commissioning request the firmware would refuse or could not run; ``field`` names the
    request's parameter (steps, i_test_a, spin_rpm)."""

    def __init__(self, field: str, message: str):
        super().__init__(message)
        self.field = field


def commission_request(
    profile: Profile,
    steps: Iterable[str] | None = None,
    i_test_a: float | None = None,
    spin_rpm: float | None = None,
) -> tuple[str, dict[str, float | int]]:
    """The config_commission message: which steps (names, default all), the test current and the
    spin speed (defaults: half the motor's current and speed limits). Raises RequestError for what
    the firmware refuses (fw_cmd.c: a test current outside (0, i_max_a], a spin speed outside
    (0, speed_max_rpm]; 0 would mean the default there, so it is refused here) and for a step
    without the step whose result it needs (STEP_NEEDS)."""
    m = profile.motor
    names = list(steps) if steps else list(STEPS)
    unknown = [s for s in names if s not in STEPS]
    if unknown:
        raise RequestError(
            "steps", f"unknown commissioning step(s) {', '.join(unknown)}: {', '.join(STEPS)}"
        )
    for s in names:
        missing = [n for n in STEP_NEEDS.get(s, ()) if n not in names]
        if missing:
            raise RequestError(
                "steps",
                f"step {s} needs step {', '.join(missing)} in the same sequence (it uses the "
                f"measured inverter distortion; docs/commissioning.md): add {', '.join(missing)}",
            )
    if i_test_a is not None and not 0.0 < i_test_a <= m.i_max_a:
        raise RequestError(
            "i_test_a",
            f"the test current must be in (0, {m.i_max_a:g}] A (the motor file's i_max_a, "
            f"{m.name}); default {0.5 * m.i_max_a:g} A",
        )
    if spin_rpm is not None and not 0.0 < spin_rpm <= m.speed_max_rpm:
        raise RequestError(
            "spin_rpm",
            f"the spin speed must be in (0, {m.speed_max_rpm:g}] r/min (the motor file's "
            f"speed_max_rpm, {m.name}); default {0.5 * m.speed_max_rpm:g} r/min (to skip the "
            "spin, leave psi_f out of the steps)",
        )
    mask = 0
    for s in names:
        mask |= 1 << gen.ENUMS["commission_step"][s]
    return "config_commission", dict(
        steps=mask,
        i_test_a=float(i_test_a if i_test_a is not None else 0.5 * m.i_max_a),
        spin_rpm=float(spin_rpm if spin_rpm is not None else 0.5 * m.speed_max_rpm),
    )


def angle_warning(profile: Profile, steps: Iterable[str] | None) -> str | None:
    """What to tell before a sequence without the encoder step whose other steps need the rotor
    angle, when the motor file's encoder offset was not measured by commissioning."""
    names = list(steps) if steps else list(STEPS)
    using = [s for s in names if s in ANGLE_STEPS]
    if "encoder" in names or not using or profile.motor.commissioning:
        return None
    return (
        f"without the encoder step, the steps {', '.join(using)} take the rotor angle from the "
        f"motor file's enc_offset_e_rad = {profile.motor.enc_offset_e_rad:g} rad, which "
        "commissioning has not measured: if the encoder's zero is off it, they fail "
        "(implausible); add encoder"
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
            out.failure = failure_text(
                row["step"],
                row["status"],
                row,
                profile.motor.pole_pairs,
                encoder_counts(profile.rig) // 4,
            )
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
        write_text_whole(motor_out, text)
    return profile, res
