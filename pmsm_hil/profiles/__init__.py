"""Profile, motor and rig YAML files: loading, validation with file:line messages, link budget.

    from pmsm_hil.profiles import load_profile, ProfileError
    profile = load_profile("profiles/paper-a.yaml")
    profile.motor.l_d_h, profile.rig.enabled("dead_time"), profile.segment_at(5.2)

The formats are documented in docs/profiles.md.
"""

from ._source import Problem, ProfileError
from .motor import Motor, load_motor, mtpa_currents, mtpa_torque_nm
from .profile import (
    FRAME_OVERHEAD_OCTETS,
    MAX_SEGMENTS,
    MAX_TOTAL_DURATION_S,
    PAYLOAD_OCTETS,
    TS_MAX_S,
    TS_MIN_S,
    Control,
    Link,
    Profile,
    Segment,
    Telemetry,
    link_budget,
    load_profile,
)
from .rig import (
    EFFECT_BITS,
    AdcNoise,
    AdcQuantisation,
    DeadTime,
    Effect,
    Effects,
    Encoder,
    Friction,
    Rig,
    load_rig,
)

__all__ = [
    "EFFECT_BITS",
    "FRAME_OVERHEAD_OCTETS",
    "MAX_SEGMENTS",
    "MAX_TOTAL_DURATION_S",
    "PAYLOAD_OCTETS",
    "TS_MAX_S",
    "TS_MIN_S",
    "AdcNoise",
    "AdcQuantisation",
    "Control",
    "DeadTime",
    "Effect",
    "Effects",
    "Encoder",
    "Friction",
    "Link",
    "Motor",
    "Problem",
    "Profile",
    "ProfileError",
    "Rig",
    "Segment",
    "Telemetry",
    "link_budget",
    "load_motor",
    "load_profile",
    "load_rig",
    "mtpa_currents",
    "mtpa_torque_nm",
]
