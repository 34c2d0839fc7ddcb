"""Why a run faulted, when the profile's own load step is the likely cause: a speed or current
trip within a few speed-loop periods of a segment whose load differs from the one before it.

A load torque step ΔT on the rotor's inertia J changes the speed at ΔT / J until the speed loop
answers (a few of its periods): on a light rotor that is tens of r/min per millisecond, and near the
top speed the overshoot when a load comes off passes `speed_trip_rpm` (the SEW CM3C80S at
600 r/min: 5 N m on 6e-4 kg m^2, 80 r/min per ms, over_speed 3 ms after the load came off)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

# a fault this soon after the segment began is put down to its step (the speed loop answers a
# step within a few of its periods; paper A's load steps recover in 24-39 ms)
WINDOW_S = 0.05
SPEED_FAULTS = ("over_speed",)
CURRENT_FAULTS = ("over_current",)


def load_step_hint(events: Iterable[tuple[float, str, Any, str]], profile: Any) -> str | None:
    """A sentence tying the run's first fault to the load step of the segment it came in, or None
    (no fault, not soon after a segment began, or that segment keeps the load as it was).
    ``events``: (t_s, kind, arg, text) as the recorder keeps them (LiveState.events)."""
    seg_t, seg_i = None, None
    for t_s, kind, arg, text in events:
        if kind == "segment_start":
            seg_t, seg_i = t_s, int(arg)
        elif kind == "fault":
            return _hint(t_s, text, seg_t, seg_i, profile)
    return None


def _hint(t_fault: float, text: str, seg_t, seg_i, profile) -> str | None:
    segs = profile.segments
    if seg_t is None or seg_i is None or not 0 < seg_i < len(segs):
        return None
    dt_s = t_fault - seg_t
    if not 0.0 <= dt_s <= WINDOW_S:
        return None
    before, now = segs[seg_i - 1].load_nm, segs[seg_i].load_nm
    if before == now:
        return None
    m = profile.motor
    rate = abs(now - before) / m.j_kgm2 * 30.0 / math.pi / 1000.0  # r/min per ms
    which = "off" if abs(now) < abs(before) else "on"
    kind = "speed" if any(f in text for f in SPEED_FAULTS) else "current"
    if kind == "current" and not any(f in text for f in CURRENT_FAULTS):
        return None
    advice = (
        "a smaller step, or the step further from speed_max_rpm, keeps the overshoot inside "
        "speed_trip_rpm"
        if kind == "speed"
        else "the speed loop's answer to it asked for more current than the trip allows"
    )
    return (
        f"the fault came {1000 * dt_s:.1f} ms after segment {seg_i} '{segs[seg_i].name}' began, "
        f"where the load steps {which} ({before:g} -> {now:g} N m): on j_kgm2 {m.j_kgm2:g} kg m^2 "
        f"the step alone changes the speed by {rate:.3g} r/min per ms until the speed loop "
        f"answers; {advice}"
    )
