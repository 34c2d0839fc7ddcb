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
    "load_profile",
    "load_motor",
    "load_rig",
    "link_budget",
    "Profile",
    "Motor",
    "Rig",
    "Segment",
    "Control",
    "Telemetry",
    "Link",
    "Effect",
    "Effects",
    "DeadTime",
    "AdcNoise",
    "AdcQuantisation",
    "Encoder",
    "Friction",
    "EFFECT_BITS",
    "ProfileError",
    "Problem",
    "mtpa_currents",
    "mtpa_torque_nm",
    "TS_MIN_S",
    "TS_MAX_S",
    "MAX_TOTAL_DURATION_S",
    "MAX_SEGMENTS",
    "FRAME_OVERHEAD_OCTETS",
    "PAYLOAD_OCTETS",
]
