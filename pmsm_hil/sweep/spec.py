"""Sweep files (sweeps/*.yaml): a base profile, the axes to vary, the metrics to keep.

    name: tolerance
    profile: paper-a-identify          # a path (relative to the sweep file) or a shipped name
    rig: lab-typical                   # optional: instead of the profile's rig
    draws: 16                          # random draws (each draws every random axis once)
    draw_seed: 1
    axes:
      - {field: motor.r_s_ohm, normal: {mean: 1.0, std: 0.05}, relative: true}
      - {field: rig.effects.dead_time.dead_time_s, uniform: {low: 1.5e-6, high: 3.0e-6}}
      - {field: rig, values: [default, lab-typical]}   # a whole rig (or motor) file per run
      - {field: seed, values: [1, 2]}
    metrics: [speed_error, ripple, identification, faults, completeness]
    keep_logs: false
    commission: true                   # each run commissions its drive first (docs/sweep.md)

Validated with pydantic; every problem is reported as ``file:line: field = value message`` through
the profile machinery (pmsm_hil/profiles/_source.py). The format is in docs/sweep.md.
"""

from __future__ import annotations

import os
import re
from typing import Literal

from pydantic import Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from pmsm_hil.profiles._base import StrictModel
from pmsm_hil.profiles._source import Problem, ProfileError, Source, read_source, resolve_ref
from pmsm_hil.profiles._validation import validation_problems
from pmsm_hil.seeds import SEED_MAX

__all__ = [
    "FIELD_RE",
    "FILE_AXES",
    "METRICS",
    "Axis",
    "Sweep",
    "SweepFile",
    "factor_column",
    "load_sweep",
]

METRICS = ("speed_error", "ripple", "recovery", "faults", "completeness", "identification", "angle")
# profile.FIELD.PATH / motor.FIELD / rig.FIELD.PATH (list items as [i]), seed, or a whole motor or
# rig file (FILE_AXES)
FIELD_RE = re.compile(r"^(seed|motor|rig|(profile|motor|rig)(\.[a-z_][a-z0-9_]*(\[\d+\])?)+)$")
FILE_AXES = ("motor", "rig")  # an axis of files (or shipped names): each run's motor or rig file
FIELDS_SAID = (
    "seed, rig, motor (files or shipped names), profile.PATH, motor.FIELD or rig.PATH "
    "(e.g. rig.effects.dead_time.dead_time_s, profile.segments[2].load_nm)"
)
MAX_RUNS = 100_000


class Normal(StrictModel):
    mean: float = Field(description="mean of the normal distribution")
    std: float = Field(gt=0, description="standard deviation")


class Range(StrictModel):
    low: float = Field(description="lower bound")
    high: float = Field(description="upper bound")

    @model_validator(mode="after")
    def _ordered(self):
        if self.high < self.low:  # a custom error: its message as it is ("value error, " not)
            raise PydanticCustomError(
                "sweep_range", f"high {self.high:g} is below low {self.low:g}"
            )
        return self


class Linspace(StrictModel):
    start: float = Field(description="first value")
    stop: float = Field(description="last value")
    num: int = Field(ge=1, le=MAX_RUNS, description="number of values")


class Axis(StrictModel):
    """One swept field: a list of values or a linspace (grid), or a distribution (random)."""

    field: str = Field(
        min_length=1,
        description="what is varied: seed, rig or motor (a file or shipped name per run), "
        "profile.PATH, motor.FIELD or rig.PATH, e.g. rig.effects.dead_time.dead_time_s",
    )
    values: list[float | int | bool | str] | None = Field(
        None, min_length=1, description="grid values"
    )
    linspace: Linspace | None = Field(None, description="grid: {start, stop, num}")
    uniform: Range | None = Field(None, description="random: uniform on {low, high}")
    normal: Normal | None = Field(None, description="random: normal {mean, std}")
    log_uniform: Range | None = Field(
        None, description="random: log-uniform on {low, high} (both > 0)"
    )
    relative: bool = Field(False, description="the values are factors on the base file's value")

    @model_validator(mode="after")
    def _one_kind(self):
        given = [
            k
            for k in ("values", "linspace", "uniform", "normal", "log_uniform")
            if getattr(self, k) is not None
        ]
        if len(given) != 1:
            raise PydanticCustomError(
                "sweep_axis_kind",
                "give exactly one of values, linspace, uniform, normal, log_uniform"
                + (f" (given: {', '.join(given)})" if given else ""),
            )
        return self

    @property
    def kind(self) -> str:
        for k in ("values", "linspace", "uniform", "normal", "log_uniform"):
            if getattr(self, k) is not None:
                return k
        raise AssertionError

    @property
    def random(self) -> bool:
        return self.kind in ("uniform", "normal", "log_uniform")

    @property
    def name(self) -> str:
        """The field with dots and brackets as _: the column of the value the run's files hold
        (for a relative axis the absolute value, in the field's unit)."""
        return "seed" if self.field == "seed" else re.sub(r"[.\[\]]+", "_", self.field).strip("_")

    @property
    def column(self) -> str:
        """The axis's column in the results: ``name``, or for a relative axis the factor's column
        (``factor_column(name)``: ``motor_r_s_ohm`` -> ``motor_r_s_factor``)."""
        return factor_column(self.name) if self.relative else self.name

    @property
    def columns(self) -> list[str]:
        """Every results column of the axis: the factor and the absolute value when relative."""
        return [self.column, self.name] if self.relative else [self.name]


# the unit at the end of a field's name (docs/profiles.md); the longest first
_UNIT_SUFFIX = re.compile(
    r"_(a_per_rad_s|rad_s|rpm_s|per_k|j_k|k_w|kgm2|nms|ohm|wb|nm|rpm|hz|rad|h|s|v|a|c|k|w|f)$"
)


def factor_column(name: str) -> str:
    """The column of a relative axis's factor: the field's name less its unit, ``_factor`` after
    (``motor_r_s_ohm`` -> ``motor_r_s_factor``, ``rig_effects_sensor_gain_i_b_gain`` ->
    ``rig_effects_sensor_gain_i_b_gain_factor``): a column named with a unit holds that unit."""
    return _UNIT_SUFFIX.sub("", name) + "_factor"


class SweepFile(StrictModel):
    """The sweep file as written."""

    name: str = Field(min_length=1, description="sweep name")
    description: str = Field("", description="text")
    profile: str = Field(
        min_length=1,
        description="base profile: a path relative to the sweep file, or a shipped name",
    )
    motor: str | None = Field(
        None, description="motor file or shipped name instead of the profile's"
    )
    rig: str | None = Field(None, description="rig file or shipped name instead of the profile's")
    seed: int = Field(1, ge=0, le=SEED_MAX, description="emulator seed when no axis sets it")
    axes: list[Axis] = Field(default_factory=list, description="the fields varied")
    draws: int | None = Field(None, ge=1, le=MAX_RUNS, description="number of random draws")
    draw_seed: int = Field(1, ge=0, description="seed of the random draws (not of the emulator)")
    metrics: list[Literal[METRICS]] = Field(  # type: ignore[valid-type]
        default_factory=lambda: list(METRICS), min_length=1, description="metrics kept per run"
    )
    keep_logs: bool = Field(False, description="keep each run's MCAP log in OUT/logs/")
    commission: bool = Field(
        False,
        description="each run first commissions the drive on its own rig, from its motor file "
        "as the nominal values, and plays the profile with the commissioned motor file",
    )


class Sweep:
    """A validated sweep file with its base files resolved to paths."""

    def __init__(
        self,
        spec: SweepFile,
        path: str,
        src: Source,
        profile_path: str,
        motor_path: str | None,
        rig_path: str | None,
    ):
        self.spec = spec
        self.name = spec.name
        self.path = path
        self.src = src
        self.profile_path = profile_path
        self.motor_path = motor_path
        self.rig_path = rig_path
        self.axes: list[Axis] = list(spec.axes)
        # an axis of files (`field: rig` or `motor`): its values' paths, in the values' order
        self.files: dict[str, list[str]] = {}
        # problems found in the file that do not keep its axes from being checked against the
        # base files (load_sweep(..., defer=True)): plan_runs reports them with those
        self.problems: list[Problem] = []

    def axis_line(self, i: int) -> int | None:
        return self.src.line(("axes", i, "field"))


def _resolve(
    src: Source, key: str | tuple, value: str, kind: str
) -> tuple[str | None, list[Problem]]:
    from pmsm_hil.profiles.shipped import resolve

    loc = key if isinstance(key, tuple) else (key,)
    rel = resolve_ref(src.path, value)
    if os.path.isfile(rel):
        return rel, []
    try:
        found = resolve(value, kind)
    except ProfileError as e:
        return None, [src.problem(loc, e.problems[0].message, value)]
    if not os.path.isfile(found):
        return None, [src.problem(loc, f"names a {kind} file that does not exist: {rel}", value)]
    return found, []


def _file_axis(
    src: Source, spec: SweepFile, i: int, ax: Axis
) -> tuple[list[str] | None, list[Problem]]:
    """An axis of whole files (`field: rig` or `motor`): a list of files or shipped names, each
    found as the sweep's `rig:`/`motor:` is, none twice, and not also given as the sweep's key."""
    kind = ax.field
    if ax.values is None or ax.relative:
        why = "takes values: [...] of files or shipped names (not a range, a draw or a factor)"
        return None, [src.problem(("axes", i, "field"), why, ax.field)]
    problems: list[Problem] = []
    if getattr(spec, kind) is not None:
        problems.append(
            src.problem((kind,), f"is given and swept (axes[{i}]): remove one", getattr(spec, kind))
        )
    paths: list[str] = []
    for j, v in enumerate(ax.values):
        if not isinstance(v, str):
            problems.append(
                src.problem(("axes", i, "values", j), f"is not a {kind} file or shipped name", v)
            )
            continue
        found, probs = _resolve(src, ("axes", i, "values", j), v, kind)
        problems += probs
        if found is None:
            continue
        if os.path.realpath(found) in {os.path.realpath(q) for q in paths}:
            problems.append(
                src.problem(
                    ("axes", i, "values", j), f"repeats a {kind} file (the same runs twice)", v
                )
            )
        paths.append(found)
    return (paths if not problems else None), problems


def load_sweep(path: str | os.PathLike, defer: bool = False) -> Sweep:
    """Read and validate a sweep file; raises ProfileError (file:line: field = value message).
    ``defer``: problems that leave every axis's field readable (a missing `draws`, a bad bound, a
    field swept twice) are kept on the Sweep for plan_runs, which reports them together with the
    axes that name no field of the base files: one round of corrections, not three."""
    path = os.fspath(path)
    src = read_source(path, what="sweep file")
    if src.problems:
        raise ProfileError(src.problems)
    problems: list[Problem] = list(src.soft)
    spec = None
    try:
        spec = SweepFile.model_validate(src.data)
    except ValidationError as e:
        problems += validation_problems(e, src, SweepFile)
    if spec is None:
        raise ProfileError(problems)
    resolved: dict[str, str | None] = {}
    for key, kind in (("profile", "profile"), ("motor", "motor"), ("rig", "rig")):
        value = getattr(spec, key)
        resolved[key] = None
        if value is not None:
            resolved[key], probs = _resolve(src, key, value, kind)
            problems += probs
    seen: dict[str, int] = {}
    columns: dict[str, int] = {}  # results column -> the first axis that has it
    unreadable = False  # an axis field plan_runs could not check against the base files
    files: dict[str, list[str]] = {}
    for i, ax in enumerate(spec.axes):
        if not FIELD_RE.match(ax.field):
            unreadable = True
            problems.append(src.problem(("axes", i, "field"), f"is not {FIELDS_SAID}", ax.field))
        elif ax.field in FILE_AXES and ax.field not in seen:
            found, probs = _file_axis(src, spec, i, ax)
            problems += probs
            unreadable = unreadable or found is None
            if found is not None:
                files[ax.field] = found
        if ax.field in seen:
            problems.append(
                src.problem(
                    ("axes", i, "field"), f"is swept twice (also axes[{seen[ax.field]}])", ax.field
                )
            )
        seen.setdefault(ax.field, i)
        for col in ax.columns:
            j = columns.setdefault(col, i)
            if j != i and spec.axes[j].field != ax.field:
                problems.append(
                    src.problem(
                        ("axes", i, "field"),
                        f"has the results column {col!r} of axes[{j}] "
                        f"({spec.axes[j].field}); sweep one of them",
                        ax.field,
                    )
                )
        if ax.log_uniform is not None and ax.log_uniform.low <= 0:
            problems.append(
                src.problem(("axes", i, "log_uniform", "low"), "must be > 0", ax.log_uniform.low)
            )
        if ax.field == "seed" and ax.random:
            problems.append(
                src.problem(
                    ("axes", i, "field"),
                    "is drawn at random; give the seeds as values or a linspace",
                    ax.field,
                )
            )
        if ax.relative and ax.field == "seed":
            problems.append(src.problem(("axes", i, "relative"), "cannot apply to the seed", True))
    has_random = any(a.random for a in spec.axes)
    if has_random and spec.draws is None:
        problems.append(
            src.problem(
                ("draws",),
                "is missing (required when an axis is random: the number of random draws)",
            )
        )
    if not has_random and spec.draws is not None:
        problems.append(src.problem(("draws",), "is given but no axis is random", spec.draws))
    files_ok = all(resolved[k] is not None or getattr(spec, k) is None for k in resolved)
    if problems and not (defer and files_ok and not unreadable):
        raise ProfileError(problems)
    profile_path = resolved["profile"]
    assert profile_path is not None  # the profile is required and was resolved, or a problem
    sweep = Sweep(spec, path, src, profile_path, resolved["motor"], resolved["rig"])
    sweep.problems = problems
    sweep.files = files
    return sweep
