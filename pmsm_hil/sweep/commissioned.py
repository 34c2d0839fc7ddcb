"""A sweep run that commissions its drive first (``commission: true`` in the sweep file): the
commissioning sequence on the run's own rig, from the run's motor file as its nominal values,
then the profile with the commissioned motor file -- `pmsm-hil commission --motor M --rig R
--seed S -o C` followed by `pmsm-hil run P --motor C --seed S`, in process."""

from __future__ import annotations

from pathlib import Path

from pmsm_hil.profiles import Profile, load_profile

__all__ = ["commission_then_load"]


def commission_then_load(directory: Path, seed: int) -> tuple[Profile | None, str]:
    """Commission with ``directory``'s motor.yaml and rig.yaml (log: commission.mcap there),
    write commissioned-motor.yaml beside them and load profile.yaml with it: (profile, "") or
    (None, why the commissioning did not complete)."""
    from pmsm_hil.commission.sequence import commission_in_process

    motor = directory / "commissioned-motor.yaml"
    _, res = commission_in_process(
        directory / "motor.yaml", directory / "rig.yaml", seed, directory / "commission.mcap", motor
    )
    if not res.ok:
        return None, f"commissioning: {res.failure or res.run.stop_reason}"
    return load_profile(directory / "profile.yaml", motor_override=motor), ""
