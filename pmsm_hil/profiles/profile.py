"""Run profiles (profiles/*.yaml): control settings, telemetry rates, the link, and the segments
of speed and load that the firmware plays on its own clock."""

from __future__ import annotations

import bisect
import math
import os
from typing import Any, NamedTuple

from pydantic import ValidationError

from ._base import meta_value, num
from ._source import Problem, ProfileError, Source, fmt_num, read_source, resolve_ref
from ._validation import validation_problems
from .acceptance import Acceptance, acceptance_problems
from .control_checks import control_checks
from .motor import Motor, _load_motor_source
from .plausibility import load_step_warnings, motor_warnings, ramp_warnings
from .reach import reach_checks
from .rig import Rig, _load_rig_source, plant_problems
from .sensorless_checks import sensorless_checks
from .shipped import in_file, near_name

__all__ = [
    "FRAME_OVERHEAD_OCTETS",
    "MAX_SEGMENTS",
    "MAX_TOTAL_DURATION_S",
    "PAYLOAD_OCTETS",
    "TS_MAX_S",
    "TS_MIN_S",
    "Control",
    "Link",
    "Profile",
    "Segment",
    "Telemetry",
    "link_budget",
    "load_profile",
]

from .sections import (  # noqa: F401  (re-exported)
    FRAME_OVERHEAD_OCTETS,
    MAX_SEGMENTS,
    MAX_TOTAL_DURATION_S,
    OCTETS_PER_SYMBOL,
    PAYLOAD_OCTETS,
    TS_MAX_S,
    TS_MIN_S,
    CanLinkSettings,
    Control,
    Link,
    PlantStep,
    PredictorScale,
    ProfileFile,
    Segment,
    Telemetry,
)

# ----------------------------------------------------------------------------------- the profile


class Profile:
    """A validated profile with its motor and rig."""

    def __init__(
        self,
        spec: ProfileFile,
        path: str,
        yaml_text: str,
        motor: Motor,
        rig: Rig,
        warnings: list[str] | None = None,
    ):
        self.spec = spec
        self.name: str = spec.name
        self.description: str = spec.description
        self.path: str = path
        self.yaml_text: str = yaml_text
        self.motor: Motor = motor
        self.rig: Rig = rig
        self.motor_ref: str = spec.motor
        self.rig_ref: str | None = spec.rig
        self.control: Control = spec.control
        self.telemetry: Telemetry = spec.telemetry
        self.link: Link = spec.link
        self.segments: list[Segment] = list(spec.segments)
        self.acceptance: Acceptance | None = spec.acceptance
        t = 0.0
        speed = 0.0
        for i, seg in enumerate(self.segments):
            seg._index, seg._t_start_s, seg._speed_start_rpm = i, t, speed
            t += seg.duration_s
            speed = seg.speed_end_rpm
        self.total_duration_s: float = t
        self._starts = [s.t_start_s for s in self.segments]
        self.warnings: list[str] = list(warnings or [])

    def __repr__(self) -> str:
        return (
            f"Profile({self.name!r}, {len(self.segments)} segments, {self.total_duration_s:g} s, "
            f"motor={self.motor.name!r}, rig={self.rig.name!r})"
        )

    # ------------------------------------------------------------------ rates
    @property
    def control_hz(self) -> float:
        return 1.0 / self.control.ts_s

    def divider(self, rate_hz: float) -> int:
        """Control periods per frame/loop period for ``rate_hz`` (0 for a rate of 0 = off)."""
        return 0 if rate_hz <= 0 else round(self.control_hz / rate_hz)

    @property
    def speed_div(self) -> int:
        return self.divider(self.control.speed_loop_hz)

    @property
    def v_dc_v(self) -> float:
        """DC-link voltage of the run: the rig's override, else the motor's."""
        return self.rig.v_dc_v if self.rig.v_dc_v is not None else self.motor.v_dc_v

    # ------------------------------------------------------------------ time
    def segment_at(self, t_s: float) -> Segment | None:
        """The segment that runs at device time ``t_s`` (from the start), or None outside the run."""
        if not (0.0 <= t_s < self.total_duration_s):
            return None
        return self.segments[bisect.bisect_right(self._starts, t_s) - 1]

    def reference_at(self, t_s: Any) -> tuple[Any, Any]:
        """(speed_ref_rpm, load_nm) at ``t_s`` (scalar or array); NaN outside [0, total).

        Each segment starts from the speed reference the previous one ended at (0 before the first),
        steps to speed_rpm (ramp_rpm_s = 0) or ramps towards it and holds it; the load steps to
        load_nm at the segment start.
        """
        import numpy as np  # not at import: a profile is loaded before the run needs numpy

        t = np.asarray(t_s, dtype=float)
        starts = np.array(self._starts)
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.segments) - 1)
        target = np.array([s.speed_rpm for s in self.segments])[k]
        s0 = np.array([s.speed_start_rpm for s in self.segments])[k]
        ramp = np.array([s.ramp_rpm_s for s in self.segments])[k]
        load = np.array([s.load_nm for s in self.segments])[k]
        dt = t - starts[k]
        gap = target - s0
        with np.errstate(invalid="ignore"):
            ramped = s0 + np.sign(gap) * np.minimum(ramp * dt, np.abs(gap))
        speed = np.where(ramp > 0, ramped, target)
        outside = ~((t >= 0.0) & (t < self.total_duration_s))
        speed = np.where(outside, np.nan, speed)
        load = np.where(outside, np.nan, load)
        if speed.ndim == 0:
            return float(speed), float(load)
        return speed, load

    # ------------------------------------------------------------------ for the log
    @property
    def files(self) -> list[tuple[str, str, str]]:
        """(role, path, text) of every file read: profile, motor, rig."""
        return [
            ("profile", self.path, self.yaml_text),
            ("motor", self.motor.path, self.motor.yaml_text),
            ("rig", self.rig.path, self.rig.yaml_text),
        ]

    @property
    def yaml_texts(self) -> dict[str, str]:
        """Attachment name -> text: {"profile.yaml": ..., "motor.yaml": ..., "rig.yaml": ...}."""
        return {f"{role}.yaml": text for role, _, text in self.files}

    def attachments(self) -> list[tuple[str, str, bytes]]:
        """MCAP attachments: profile.yaml, motor.yaml, rig.yaml (the files' exact text)."""
        return [
            (f"{role}.yaml", "application/yaml", text.encode("utf-8"))
            for role, _, text in self.files
        ]

    def metadata(self) -> dict[str, dict[str, str]]:
        """MCAP metadata records "profile", "motor" and "rig" (all values as text)."""
        import hashlib

        prof = {
            "name": self.name,
            "file": os.path.basename(self.path),
            "sha256": hashlib.sha256(self.yaml_text.encode("utf-8")).hexdigest(),
            "total_duration_s": meta_value(self.total_duration_s),
            "segments": str(len(self.segments)),
        }
        for section in ("control", "telemetry", "link"):
            for k, v in getattr(self, section).model_dump().items():
                if isinstance(v, dict):
                    for k2, v2 in v.items():
                        prof[f"{section}.{k}.{k2}"] = meta_value(v2)
                else:
                    prof[f"{section}.{k}"] = meta_value(v)
        return {"profile": prof, "motor": self.motor.metadata(), "rig": self.rig.metadata()}

    def link_budget(self, **kw: Any) -> dict:
        return link_budget(self, **kw)


# ----------------------------------------------------------------------------------- link budget


class Sections(NamedTuple):
    """The sections of a profile that its link budget reads (of a file that has other problems)."""

    control: Control
    telemetry: Telemetry
    link: Link


def link_budget(
    profile: Profile | Sections, *, emulator: bool = True, n_estimators: int | None = None
) -> dict:
    """Octets/s that each telemetry stream needs against the serial link's capacity (baud / 10).

    Returns {"capacity_octets_s", "streams": {name: {"rate_hz", "count", "payload_octets",
    "frame_octets", "octets_s", "share"}}, "total_octets_s", "load" (fraction), "headroom_octets_s",
    "warning" (text or None)}. ``sim_truth`` counts only with ``emulator``; ``params`` is sent once
    per running estimator: the nominal frame, plus RLS, Adaline and NLMS-Adaline when
    ``control.identify`` is on (``n_estimators`` None: derived from the profile).
    """
    if n_estimators is None:
        n_estimators = 4 if profile.control.identify else 1
    tel = profile.telemetry
    rates = {
        "telem_fast": (tel.fast_hz, 1),
        "params": (tel.params_hz, n_estimators),
        "status": (tel.status_hz, 1),
        "sim_truth": (tel.truth_hz if emulator else 0.0, 1),
        "telem_est": (tel.est_hz if profile.control.angle_src != "encoder" else 0.0, 1),
    }
    capacity = profile.link.baud / OCTETS_PER_SYMBOL
    streams: dict[str, dict] = {}
    total = 0.0
    for name, (hz, count) in rates.items():
        frame = PAYLOAD_OCTETS[name] + FRAME_OVERHEAD_OCTETS
        octets = hz * count * frame
        total += octets
        streams[name] = {
            "rate_hz": hz,
            "count": count,
            "payload_octets": PAYLOAD_OCTETS[name],
            "frame_octets": frame,
            "octets_s": octets,
            "share": octets / capacity,
        }
    load = total / capacity
    warning = None
    others = total - streams["telem_fast"]["octets_s"]
    frame = streams["telem_fast"]["frame_octets"]
    fit = max((capacity - others) / frame, 0.0)
    ctrl = 1.0 / profile.control.ts_s
    n = math.ceil(ctrl / fit) if fit > 0 else 0
    fast_hz_fit = min(tel.fast_hz, round(ctrl / n, 6)) if n else 0.0
    if load > 1.0:
        hint = (
            f"lower telemetry.fast_hz to {fmt_num(round(ctrl / n, 6))} Hz or less"
            if n
            else "lower the telemetry rates"
        )
        warning = (
            f"link overloaded: the telemetry needs {total:.0f} octets/s but {profile.link.baud} baud "
            f"carries {capacity:.0f} octets/s ({100 * load:.0f} %); frames will be dropped. "
            f"{hint[0].upper() + hint[1:]}, or raise link.baud."
        )
    return {
        "capacity_octets_s": capacity,
        "streams": streams,
        "total_octets_s": total,
        "load": load,
        "headroom_octets_s": capacity - total,
        "warning": warning,
        "fast_hz_fit": fast_hz_fit,
    }


# ----------------------------------------------------------------------------------- loading


def _divides(ctrl_hz: float, hz: float) -> bool:
    n = ctrl_hz / hz
    return abs(n - round(n)) <= 1e-6 * max(n, 1.0)


def _rate_problem(src: Source, loc: tuple, hz: float, ctrl_hz: float) -> Problem | None:
    if hz <= 0:
        return None
    if hz > ctrl_hz * (1 + 1e-9):
        return src.problem(
            loc, f"is above the control rate {fmt_num(round(ctrl_hz, 6))} Hz (1/control.ts_s)", hz
        )
    if _divides(ctrl_hz, hz):
        return None
    n = ctrl_hz / hz
    cands = sorted({round(ctrl_hz / m, 6) for m in (math.floor(n), math.ceil(n)) if m >= 1})
    return src.problem(
        loc,
        f"does not divide the control rate {fmt_num(round(ctrl_hz, 6))} Hz "
        f"(1/control.ts_s); nearest valid: "
        f"{' or '.join(fmt_num(c) for c in cands)} Hz",
        hz,
    )


def _profile_checks(src: Source, motor: Motor | None) -> tuple[list[Problem], list[str]]:
    """Checks across fields and files on the raw data (so they run even when pydantic found
    problems elsewhere); values of the wrong type are skipped here (pydantic reports them)."""
    d = src.data
    problems: list[Problem] = []
    warnings: list[str] = []
    control = d.get("control") if isinstance(d.get("control"), dict) else {}
    telemetry = d.get("telemetry") if isinstance(d.get("telemetry"), dict) else {}
    defaults_c, defaults_t = Control.model_fields, Telemetry.model_fields

    ts = num(control, "ts_s", defaults_c["ts_s"].default)
    if ts is not None and TS_MIN_S <= ts <= TS_MAX_S:
        ctrl_hz = 1.0 / ts
        for key in ("fast_hz", "params_hz", "status_hz", "truth_hz", "est_hz"):
            hz = num(telemetry, key, defaults_t[key].default)
            if hz is not None and hz >= 0:
                p = _rate_problem(src, ("telemetry", key), hz, ctrl_hz)
                if p:
                    problems.append(p)
        hz = num(control, "speed_loop_hz", defaults_c["speed_loop_hz"].default)
        if hz is not None and hz > 0:
            p = _rate_problem(src, ("control", "speed_loop_hz"), hz, ctrl_hz)
            if p:
                problems.append(p)

    kp_given = control.get("speed_kp_a_per_rad_s") is not None
    ki_given = control.get("speed_ki_a_per_rad") is not None
    if kp_given != ki_given:
        missing = "speed_ki_a_per_rad" if kp_given else "speed_kp_a_per_rad_s"
        given = "speed_kp_a_per_rad_s" if kp_given else "speed_ki_a_per_rad"
        problems.append(
            src.problem(
                ("control", given),
                f"is given but control.{missing} is not: give both "
                f"speed gains, or neither to have them designed",
                control.get(given),
            )
        )

    segments = d.get("segments") if isinstance(d.get("segments"), list) else []
    ctrl_problems, ctrl_warnings = control_checks(src, control, segments, ts)
    problems += ctrl_problems
    warnings += ctrl_warnings
    total = 0.0
    speed = 0.0
    mpath = motor.path if motor is not None else ""
    for i, seg in enumerate(segments):
        if not isinstance(seg, dict):
            continue
        dur = num(seg, "duration_s")
        v = num(seg, "speed_rpm")
        load = num(seg, "load_nm", 0.0)
        ramp = num(seg, "ramp_rpm_s", 0.0)
        if dur is not None and dur > 0:
            total += dur
        if seg.get("kind") == "identify_r":
            if v is not None and v != 0:
                problems.append(
                    src.problem(
                        ("segments", i, "speed_rpm"),
                        "must be 0 in an identify_r segment (R is identified at standstill)",
                        v,
                    )
                )
            inj = num(seg, "inject_a", 0.0)
            if inj is not None and inj == 0:
                problems.append(
                    src.problem(
                        ("segments", i, "inject_a"),
                        "must be a non-zero d current in an identify_r segment",
                        inj,
                    )
                )
            if motor is not None and inj is not None and abs(inj) > motor.i_max_a:
                problems.append(
                    src.problem(
                        ("segments", i, "inject_a"),
                        f"is beyond the motor's i_max_a {fmt_num(motor.i_max_a)} ({mpath})",
                        inj,
                    )
                )
        if motor is not None and v is not None and abs(v) > motor.speed_max_rpm * (1 + 1e-12):
            problems.append(
                src.problem(
                    ("segments", i, "speed_rpm"),
                    f"is beyond the motor's speed_max_rpm {fmt_num(motor.speed_max_rpm)} ({mpath})",
                    v,
                )
            )
        if motor is not None and load is not None and abs(load) > motor.torque_max_nm * (1 + 1e-12):
            problems.append(
                src.problem(
                    ("segments", i, "load_nm"),
                    f"is beyond the motor's torque_max_nm {fmt_num(motor.torque_max_nm)} ({mpath})",
                    load,
                )
            )
        if v is None or dur is None or ramp is None or dur <= 0 or ramp < 0:
            speed = v if v is not None else speed
            continue
        if ramp > 0:
            gap = v - speed
            reach = ramp * dur
            if abs(gap) > reach:
                end = speed + math.copysign(reach, gap)
                warnings.append(
                    f"{src.path}:{src.line(('segments', i, 'ramp_rpm_s'))}: segments[{i}]: the ramp "
                    f"of {fmt_num(ramp)} r/min/s reaches only {end:.4g} of {fmt_num(v)} r/min "
                    f"within duration_s {fmt_num(dur)} (needs {abs(gap) / ramp:.3g} s)"
                )
                speed = end
                continue
        speed = v
    if "acceptance" in d and d["acceptance"] is None:
        warnings.append(
            f"{src.path}:{src.line(('acceptance',))}: acceptance: is empty (its criteria not "
            "indented under it?): a run is judged on the defaults only, complete and no fault"
        )
    if total > MAX_TOTAL_DURATION_S * (1 + 1e-12):
        problems.append(
            src.problem(
                ("segments",),
                f"last {total:.6g} s in total, beyond the {fmt_num(MAX_TOTAL_DURATION_S)} s limit",
            )
        )
    return problems, warnings


def _rig_checks(rig_src: Source, rig: Rig, motor: Motor, src: Source) -> list[Problem]:
    """Checks of the rig file against the motor file and the profile's control period."""
    problems: list[Problem] = []
    v = num(rig_src.data, "v_dc_v")
    if v is not None and not (motor.v_dc_min_v < v < motor.v_dc_max_v):
        problems.append(
            rig_src.problem(
                ("v_dc_v",),
                f"is outside the motor's DC-link trip limits "
                f"v_dc_min_v {fmt_num(motor.v_dc_min_v)} .. v_dc_max_v "
                f"{fmt_num(motor.v_dc_max_v)} V ({motor.path})",
                v,
            )
        )
    control = src.data.get("control") if isinstance(src.data.get("control"), dict) else {}
    ts = num(control, "ts_s", Control.model_fields["ts_s"].default)
    if ts is None or not TS_MIN_S <= ts <= TS_MAX_S:
        ts = None
    return problems + plant_problems(rig_src, rig, rig.plant_pole_pairs(motor.pole_pairs), ts)


def load_profile(
    path: str | os.PathLike,
    rig_override: str | os.PathLike | None = None,
    motor_override: str | os.PathLike | None = None,
) -> Profile:
    """Read and validate a profile with its motor and rig files.

    ``rig_override``/``motor_override``: a rig/motor file (relative to the working directory) used
    instead of the profile's (e.g. a commissioned motor file).
    Raises ProfileError listing every problem found (file:line: field = value message).
    """
    path = os.fspath(path)
    src = read_source(path, what="profile")
    if src.problems:
        raise ProfileError(src.problems)
    problems: list[Problem] = list(src.soft)
    spec: ProfileFile | None = None
    try:
        spec = ProfileFile.model_validate(src.data)
    except ValidationError as e:
        problems += validation_problems(e, src, ProfileFile)

    d = src.data
    motor: Motor | None = None
    motor_path = None
    msrc: Source | None = None
    notes: list[str] = []  # files taken from the shipped ones (shipped.in_file)
    if motor_override is not None:
        motor_path = os.fspath(motor_override)
        msrc = read_source(motor_path, what="motor file")
        motor, mprobs = _load_motor_source(msrc)
        problems += mprobs
    elif isinstance(d.get("motor"), str) and d["motor"]:
        motor_path, note = in_file(resolve_ref(path, d["motor"]), d["motor"], "motor")
        if note:
            notes.append(f"{path}:{src.line(('motor',))}: motor = {d['motor']!r}: {note}")
        msrc = read_source(
            motor_path,
            what="motor file",
            referenced_by=(src, ("motor",), d["motor"]),
            hint="" if os.path.exists(motor_path) else near_name(d["motor"], "motor"),
        )
        motor, mprobs = _load_motor_source(msrc)
        problems += mprobs

    rig: Rig | None = None
    rig_ref = d.get("rig")
    if rig_override is not None:
        rsrc = read_source(os.fspath(rig_override), what="rig file")
    elif isinstance(rig_ref, str) and rig_ref:
        rig_path, note = in_file(resolve_ref(path, rig_ref), rig_ref, "rig")
        if note:
            notes.append(f"{path}:{src.line(('rig',))}: rig = {rig_ref!r}: {note}")
        rsrc = read_source(
            rig_path,
            what="rig file",
            referenced_by=(src, ("rig",), rig_ref),
            hint="" if os.path.exists(rig_path) else near_name(rig_ref, "rig"),
        )
    elif rig_ref is None:
        base = os.path.dirname(os.path.dirname(motor_path)) if motor_path else os.path.dirname(path)
        rig_path, note = in_file(
            os.path.normpath(os.path.join(base, "rigs", "default.yaml")), "rigs/default.yaml", "rig"
        )
        if note:
            notes.append(f"{path}: no rig given, and {note}")
        rsrc = read_source(
            rig_path,
            what="rig file",
            referenced_by=(src, ("rig",), None) if os.path.exists(rig_path) else None,
        )
        if not os.path.exists(rig_path):
            rsrc.problems[:] = [
                src.problem(("rig",), f"is not given and the default rig {rig_path} does not exist")
            ]
    else:
        rsrc = None  # wrong type: pydantic reports it
    if rsrc is not None:
        rig, rprobs = _load_rig_source(rsrc)
        problems += rprobs
        if rig is not None and motor is not None:
            problems += _rig_checks(rsrc, rig, motor, src)
        if rprobs:  # a rig whose flux map cannot be used: checked above, not reached below
            rig = None

    checks, warnings = _profile_checks(src, motor)
    problems += checks + acceptance_problems(src)
    if motor is not None and rig is not None:
        reach_problems, reach_warnings = reach_checks(src, motor, rig)
        problems += reach_problems
        warnings += reach_warnings
    if motor is not None and msrc is not None:
        snl_problems, snl_warnings = sensorless_checks(src, motor, msrc)
        problems += snl_problems
        ts = spec.control.ts_s if spec is not None else None
        warnings += snl_warnings + motor_warnings(motor, msrc, ts) + ramp_warnings(src, motor)
        kp = spec.control.speed_kp_a_per_rad_s if spec is not None else None
        warnings += load_step_warnings(src, motor, kp)
    if problems:
        raise ProfileError(_ordered(problems), _budget_warnings(src, path, problems))
    assert spec is not None and motor is not None and rig is not None
    profile = Profile(spec, path, src.text, motor, rig, notes + warnings)
    budget = link_budget(profile)
    if budget["warning"]:
        profile.warnings.append(f"{path}:{src.line(('telemetry',))}: {budget['warning']}")
    return profile


def _budget_warnings(src: Source, path: str, problems: list[Problem]) -> list[str]:
    """The link-budget warning of a file with other problems, when its control, telemetry and
    link sections have none: with the problems, not after they are fixed."""
    if any(
        p.file == path and (p.field or "").startswith(("control", "telemetry", "link"))
        for p in problems
    ):
        return []
    d = src.data if isinstance(src.data, dict) else {}
    try:
        budget = link_budget(
            Sections(
                Control.model_validate(d.get("control") or {}),
                Telemetry.model_validate(d.get("telemetry") or {}),
                Link.model_validate(d.get("link") or {}),
            )
        )
    except (ValidationError, TypeError, ValueError):
        return []
    warning = budget["warning"]
    return [f"{path}:{src.line(('telemetry',))}: {warning}"] if warning else []


def _ordered(problems: list[Problem]) -> list[Problem]:
    """Group by file in order of first appearance, then by line (stable); drop exact duplicates."""
    order: dict[str, int] = {}
    for p in problems:
        order.setdefault(p.file, len(order))
    seen = set()
    out = []
    for p in sorted(problems, key=lambda p: (order[p.file], p.line if p.line is not None else 0)):
        key = str(p)
        if key not in seen:
            seen.add(key)
            out.append(p)
    return out
