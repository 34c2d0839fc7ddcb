"""The current step of the finite-control-set MPCC: one control period of an active voltage vector
(2/3 v_dc in the amplitude-invariant frame) moves the current by about 2/3 v_dc ts_s / L. The MPCC
picks one switching state per period, so its current ripple scales with that step; on a motor of
low inductance the ripple's slow part shakes the speed, most at low speed (docs/control.md, "A
motor of low inductance")."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .control_checks import profile_controllers

if TYPE_CHECKING:
    from .profile import Profile

# The step's share of i_max_a above which a speed miss on an MPCC segment is put down to it.
# Measured on paper A's profile with its motor's inductances scaled down (seeds 1-3): at 24 %
# (the motor as published) every criterion passes; at 36 % and above the 15 r/min load step's
# recovery misses on every seed, and FOC on the same motors passes down to 1/8 of the inductance.
STEP_SHARE_HINT = 0.3


@dataclass(frozen=True)
class CurrentStep:
    step_a: float  # 2/3 v_dc ts_s / min(L_d, L_q)
    i_max_a: float
    v_dc_v: float
    ts_s: float
    l_min_h: float
    mpcc_segments: tuple[int, ...]  # the segments the MPCC controls the current in

    @property
    def share(self) -> float:
        """The step as a share of i_max_a."""
        return self.step_a / self.i_max_a


def current_step(profile: Profile) -> CurrentStep:
    """The MPCC's current step on the run's DC link and the segments that run the MPCC (a
    segment's ``current_ctrl``, else the previous segment's, else ``control.current_ctrl``)."""
    motor, v_dc = profile.motor, profile.v_dc_v
    l_min = min(motor.l_d_h, motor.l_q_h)
    mpcc = [i for i, ctrl in enumerate(profile_controllers(profile)) if ctrl == "mpcc"]
    ts = profile.control.ts_s
    return CurrentStep(2.0 / 3.0 * v_dc * ts / l_min, motor.i_max_a, v_dc, ts, l_min, tuple(mpcc))
