"""The runs of a sweep: the axes expanded (grid product x random draws) and each run's inputs made
concrete as three YAML texts (profile, motor, rig) and a seed, keyed by a hash of them.

Order: for each random draw (one when no axis is random), the grid axes' Cartesian product in the
order the axes are written (the last axis varies fastest). The random draws come from one numpy
generator seeded by ``draw_seed``, so a sweep file always expands to the same runs.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import os
import re
from dataclasses import dataclass, field
from typing import Annotated, Any

import numpy as np
import yaml
from pydantic import ConfigDict, TypeAdapter, ValidationError

from pmsm_hil.names import did_you_mean
from pmsm_hil.profiles import Profile, ProfileError, load_profile
from pmsm_hil.profiles._source import Problem, fmt_value, loc_str, read_source, resolve_ref
from pmsm_hil.profiles._validation import error_message, resolve_field
from pmsm_hil.seeds import SEED_MAX

from .spec import FILE_AXES, Axis, Sweep

__all__ = ["Run", "axis_values", "materialise", "plan_runs", "profile_run"]

FILES = ("profile.yaml", "motor.yaml", "rig.yaml")
_PART = re.compile(r"([a-z_][a-z0-9_]*)(?:\[(\d+)\])?")


@dataclass
class Run:
    index: int
    values: dict[str, Any]  # results column of an axis (Axis.columns) -> value
    seed: int
    texts: dict[str, str] = field(default_factory=dict)  # FILES -> YAML text
    key: str = ""
    commission: bool = False  # commission the drive on the run's rig first (sweep file)

    def task(self, metrics: list[str], log_path: str | None) -> dict:
        """What a worker needs: plain data (picklable, no paths to read), and the firmware build
        the run was planned for (a worker with another build refuses it)."""
        from pmsm_hil.emulator.fwlib import source_id

        return {
            "key": self.key,
            "firmware": source_id(),
            "index": self.index,
            "seed": self.seed,
            "texts": dict(self.texts),
            "metrics": list(metrics),
            "log_path": log_path,
            "commission": self.commission,
        }


def _parts(path: str) -> list[str | int]:
    out: list[str | int] = []
    for name in path.split("."):
        m = _PART.fullmatch(name)
        assert m is not None
        out.append(m.group(1))
        if m.group(2) is not None:
            out.append(int(m.group(2)))
    return out


class _NoField(KeyError):
    """``parts`` names nothing: ``part`` is not in ``obj``, reached by ``where`` (for _unknown)."""

    def __init__(self, obj: Any, where: str, part: str | int):
        super().__init__(part)
        self.obj, self.where, self.part = obj, where, part


def _base_value(obj: Any, parts: list[str | int]) -> Any:
    """The value at ``parts`` in the loaded (validated, defaults filled) objects; _NoField (a
    KeyError) if the path names nothing there."""
    where = ""
    for p in parts:
        if isinstance(p, int):
            if not isinstance(obj, (list, tuple)) or p >= len(obj):
                raise _NoField(obj, where, p)
            obj, where = obj[p], f"{where}[{p}]"
        elif hasattr(type(obj), "model_fields") and p in type(obj).model_fields:
            obj, where = getattr(obj, p), f"{where}.{p}".lstrip(".")
        else:
            raise _NoField(obj, where, p)
    return obj


def _unknown(e: _NoField, root: str) -> str:
    """Why a path names nothing: the index beyond its list's length, or the name with the nearest
    known one (or the known ones)."""
    obj, where, p = e.obj, e.where, e.part
    if isinstance(p, int):
        if not isinstance(obj, (list, tuple)):
            return f"{where} is not a list"
        n = len(obj)
        return f"{where} has {n} item{'s' if n != 1 else ''}" + (f": 0..{n - 1}" if n else "")
    known = list(type(obj).model_fields) if hasattr(type(obj), "model_fields") else []
    if not known:
        return f"{where} is a value, it has no {p!r}"
    hint = did_you_mean(p, known)
    if hint:
        return f"{p!r} is unknown{hint}"
    return f"{p!r} is unknown; {where or 'the ' + root} has {', '.join(known)}"


def _set(data: dict, parts: list[str | int], value: Any) -> None:
    obj: Any = data
    for p, nxt in itertools.pairwise(parts):
        if isinstance(p, int):
            obj = obj[p]
        else:
            if not isinstance(obj.get(p), (dict, list)):
                obj[p] = [] if isinstance(nxt, int) else {}
            obj = obj[p]
    obj[parts[-1]] = value


def axis_values(axis: Axis, rng: np.random.Generator | None = None) -> list[Any]:
    """A grid axis' values, or one draw of a random axis (from ``rng``)."""
    if axis.values is not None:
        return list(axis.values)
    if axis.linspace is not None:
        ls = axis.linspace
        return [float(v) for v in np.linspace(ls.start, ls.stop, ls.num)]
    assert rng is not None
    if axis.uniform is not None:
        return [float(rng.uniform(axis.uniform.low, axis.uniform.high))]
    if axis.normal is not None:
        return [float(rng.normal(axis.normal.mean, axis.normal.std))]
    lu = axis.log_uniform
    assert lu is not None
    return [float(math.exp(rng.uniform(math.log(lu.low), math.log(lu.high))))]


class _Base:
    """The base profile, motor and rig as data (for editing) and as validated objects (for the
    base value of a field, defaults included)."""

    def __init__(
        self, profile_path: str, rig_path: str | None = None, motor_path: str | None = None
    ):
        self.profile = load_profile(profile_path, rig_override=rig_path, motor_override=motor_path)
        self.data = {
            "profile": read_source(self.profile.path).data,
            "motor": read_source(self.profile.motor.path).data,
            "rig": read_source(self.profile.rig.path).data,
        }
        self.objects = {
            "profile": self.profile.spec,
            "motor": self.profile.motor,
            "rig": self.profile.rig,
        }
        sat = (self.data["rig"].get("effects") or {}).get("saturation")
        if isinstance(sat, dict) and isinstance(sat.get("map"), str):
            sat["map"] = os.path.abspath(resolve_ref(self.profile.rig.path, sat["map"]))
        # the motor's own flux map (and a commissioned file's nominal machine's), as the rig's:
        # relative to the motor file, which the run does not have beside it
        motor = self.data["motor"]
        nominal = (motor.get("commissioning") or {}).get("nominal")
        for holder in (motor, nominal if isinstance(nominal, dict) else {}):
            if isinstance(holder.get("flux_map"), str) and holder["flux_map"]:
                holder["flux_map"] = os.path.abspath(
                    resolve_ref(self.profile.motor.path, holder["flux_map"])
                )
        self.data["profile"]["motor"] = "motor.yaml"
        self.data["profile"]["rig"] = "rig.yaml"


def _seed_problems(sweep: Sweep, i: int, ax: Axis) -> list[Problem]:
    """A seed axis takes whole numbers in 0..SEED_MAX, as a list or a linspace of them (a
    drawn seed is not a seed: draws are already random)."""
    if ax.values is None and ax.linspace is None:
        return [sweep.src.problem(("axes", i, ax.kind), "a seed axis takes values: [...]", ax.kind)]
    vals = axis_values(ax)
    for j, v in enumerate(vals):
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and float(v).is_integer()
        if not ok or not 0 <= v <= SEED_MAX:
            where = ("values", j) if ax.values is not None else ("linspace",)
            return [
                sweep.src.problem(
                    ("axes", i, *where), f"is not a whole number in 0..{SEED_MAX} (a seed)", v
                )
            ]
    if len({int(v) for v in vals}) < len(vals):
        return [
            sweep.src.problem(("axes", i, "values"), "repeats a seed (the same run twice)", vals)
        ]
    return []


def _check_axes(sweep: Sweep, base: _Base, own: bool = True) -> None:
    """The axes against the base files; ``own``: with the sweep file's own problems (kept by
    load_sweep(defer=True)) and its seed axes (once, not for each file of a file axis)."""
    problems: list[Problem] = list(sweep.problems) if own else []
    for i, ax in enumerate(sweep.axes):
        if ax.field == "seed":
            problems += _seed_problems(sweep, i, ax) if own else []
            continue
        if ax.field in FILE_AXES:
            continue
        parts = _parts(ax.field)
        root, rest = str(parts[0]), parts[1:]
        try:
            value = _base_value(base.objects[root], rest)
        except _NoField as e:
            problems.append(
                sweep.src.problem(
                    ("axes", i, "field"),
                    f"names no field of the {root} ({_unknown(e, root)})",
                    ax.field,
                )
            )
            continue
        if hasattr(type(value), "model_fields") or isinstance(value, (list, dict)):
            problems.append(
                sweep.src.problem(("axes", i, "field"), "names a section, not a value", ax.field)
            )
        elif ax.relative and (isinstance(value, bool) or not isinstance(value, (int, float))):
            problems.append(
                sweep.src.problem(
                    ("axes", i, "relative"),
                    f"needs a number in the base file, which has {value!r}",
                    True,
                )
            )
    if problems:
        raise ProfileError(problems)
    problems = []
    for i, ax in enumerate(sweep.axes):
        if ax.field != "seed" and ax.field not in FILE_AXES:
            problems += _value_problems(sweep, base, i, ax)
    if problems:
        raise ProfileError(problems)


def _probe_values(ax: Axis) -> list[tuple[tuple, Any]]:
    """The values of an axis that can be checked before the sweep runs, with where each is written:
    every value of a grid, the ends of a uniform or log-uniform draw (a normal draw has none)."""
    if ax.values is not None:
        return [(("values", j), v) for j, v in enumerate(ax.values)]
    if ax.linspace is not None:
        return [(("linspace",), v) for v in axis_values(ax)]
    rng = ax.uniform if ax.uniform is not None else ax.log_uniform
    if rng is None:
        return []
    return [((ax.kind, "low"), rng.low), ((ax.kind, "high"), rng.high)]


def _value_problems(sweep: Sweep, base: _Base, i: int, ax: Axis) -> list[Problem]:
    """Each value of axis ``i`` against its field's own type and bounds in the motor, rig or
    profile (those hold whatever the other axes do): a value the field does not take is reported
    at the sweep file's line before anything runs, not at run time in a generated file. Checks
    that involve other fields (a torque limit against the current limit) stay with the run, whose
    other axes may change them. One problem per axis (its first bad value)."""
    parts = _parts(ax.field)
    root, rest = str(parts[0]), parts[1:]
    _, info = resolve_field(type(base.objects[root]), tuple(rest))
    if info is None:
        return []
    typ: Any = Annotated[(info.annotation, *info.metadata)] if info.metadata else info.annotation
    # as the models validate: strict (no "12" for 12), finite numbers only (profiles/_base.py)
    adapter: TypeAdapter[Any] = TypeAdapter(
        typ, config=ConfigDict(strict=True, allow_inf_nan=False)
    )
    base_value = _base_value(base.objects[root], rest)
    for loc, v in _probe_values(ax):
        if ax.relative and (isinstance(v, bool) or not isinstance(v, (int, float))):
            why = "is not a number (a relative axis takes factors of the base value)"
            return [sweep.src.problem(("axes", i, *loc), why, v)]
        concrete = _concrete(v, base_value, ax.relative)
        try:
            adapter.validate_python(concrete)
        except ValidationError as e:
            why = error_message(e.errors()[0], info, str(rest[-1]))
            said = f"{loc_str(tuple(rest))} = {fmt_value(concrete)} {why}"
            if ax.relative:
                said += f" (the factor {fmt_value(v)} times the base value)"
            return [
                sweep.src.problem(("axes", i, *loc), f"makes the {root} file invalid: {said}", v)
            ]
    return []


def _concrete(value: Any, base_value: Any, relative: bool) -> Any:
    if relative:
        value = base_value * value
    if (
        isinstance(base_value, int)
        and not isinstance(base_value, bool)
        and isinstance(value, float)
        and value.is_integer()
    ):
        return int(value)
    if isinstance(base_value, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def materialise(
    base: _Base, axes: list[Axis], values: dict[str, Any], seed: int
) -> tuple[dict[str, str], int, dict[str, Any]]:
    """The three YAML texts and the seed of one run (``values``: axis field -> value as drawn),
    and the results columns of its axes (``Axis.columns``: a relative axis's factor and the
    absolute value the files hold)."""
    data = copy.deepcopy(base.data)
    columns: dict[str, Any] = {}
    for ax in axes:
        v = values[ax.field]
        if ax.field == "seed":
            seed = int(v)
            columns[ax.name] = seed
            continue
        if ax.field in FILE_AXES:  # the base is that file's (_bases): the name as written
            columns[ax.name] = v
            continue
        parts = _parts(ax.field)
        root, rest = str(parts[0]), parts[1:]
        concrete = _concrete(v, _base_value(base.objects[root], rest), ax.relative)
        _set(data[root], rest, concrete)
        columns[ax.column] = v
        columns[ax.name] = concrete
    texts = {
        f"{k}.yaml": yaml.safe_dump(data[k], sort_keys=False, width=1_000_000)
        for k in ("profile", "motor", "rig")
    }
    return texts, seed, columns


def run_key(texts: dict[str, str], seed: int, commission: bool = False) -> str:
    """A hash of what a run is: its three texts, its seed, whether it commissions first and the
    firmware build that runs it (fwlib.source_id): a sweep resumed after a firmware change runs
    everything again."""
    from pmsm_hil.emulator.fwlib import source_id

    what: dict[str, Any] = {"texts": [texts[f] for f in FILES], "seed": seed}
    what["firmware"] = source_id()
    if commission:  # absent otherwise: the keys of sweeps without it are as before
        what["commission"] = True
    blob = json.dumps(what, sort_keys=True)
    return hashlib.sha256(blob.encode("utf-8")).hexdigest()[:16]


def _bases(sweep: Sweep) -> dict[tuple[str | None, str | None], _Base]:
    """The base files of every (rig, motor) value of the file axes (one base without them), each
    loaded with the profile, and the other axes checked against each: ProfileError at the sweep
    file's line of a file that does not load (with its own problems after)."""
    rigs: list[tuple[int, str | None]] = [(-1, None)]
    motors: list[tuple[int, str | None]] = [(-1, None)]
    for kind, choice in (("rig", rigs), ("motor", motors)):
        if kind in sweep.files:
            choice[:] = list(enumerate(sweep.files[kind]))
    axis_of = {ax.field: i for i, ax in enumerate(sweep.axes)}
    bases: dict[tuple[str | None, str | None], _Base] = {}
    for (j, rig), (k, motor) in itertools.product(rigs, motors):
        try:
            base = _Base(sweep.profile_path, rig or sweep.rig_path, motor or sweep.motor_path)
        except ProfileError as e:
            if not (rig or motor):
                raise
            # the file to blame: the rig when its own file has a problem, or it alone is swept
            in_rig = rig is not None and any(
                os.path.realpath(p.file) == os.path.realpath(rig) for p in e.problems
            )
            kind, n = ("rig", j) if rig and (in_rig or not motor) else ("motor", k)
            i = axis_of[kind]
            v = (sweep.axes[i].values or [])[n]
            said = "does not load with the profile (the problems below)"
            raise ProfileError(
                [sweep.src.problem(("axes", i, "values", n), said, v), *e.problems]
            ) from None
        _check_axes(sweep, base, own=not bases)
        bases[(rig, motor)] = base
    return bases


def plan_runs(sweep: Sweep) -> list[Run]:
    """Every run of the sweep, in order; raises ProfileError for an axis that names no field."""
    bases = _bases(sweep)
    paths = {
        kind: dict(zip(sweep.axes[i].values or [], sweep.files[kind], strict=True))
        for i, ax in enumerate(sweep.axes)
        if (kind := ax.field) in sweep.files
    }
    grid = [a for a in sweep.axes if not a.random]
    rand = [a for a in sweep.axes if a.random]
    rng = np.random.Generator(np.random.PCG64(sweep.spec.draw_seed))
    combos = list(itertools.product(*(axis_values(a) for a in grid)))
    runs: list[Run] = []
    for _ in range(sweep.spec.draws or 1):
        drawn = {a.field: axis_values(a, rng)[0] for a in rand}
        for combo in combos:
            by_field = dict(drawn)
            by_field.update({a.field: v for a, v in zip(grid, combo, strict=False)})
            base = bases[
                (
                    paths["rig"][by_field["rig"]] if "rig" in paths else None,
                    paths["motor"][by_field["motor"]] if "motor" in paths else None,
                )
            ]
            texts, seed, values = materialise(base, sweep.axes, by_field, sweep.spec.seed)
            com = sweep.spec.commission
            runs.append(
                Run(
                    index=len(runs),
                    values=values,
                    seed=seed,
                    texts=texts,
                    key=run_key(texts, seed, com),
                    commission=com,
                )
            )
    return runs


def profile_run(
    profile_path: str,
    index: int = 0,
    seed: int = 1,
    rig_path: str | None = None,
    motor_path: str | None = None,
    warnings: list[str] | None = None,
    loaded: list[Profile] | None = None,
) -> Run:
    """One run of a profile as it is (with another rig or motor file if given): a sweep of one
    point. Raises ProfileError for an invalid profile. ``warnings`` (a list): the profile's
    warnings are appended to it; ``loaded`` (a list): the profile as loaded."""
    base = _Base(profile_path, rig_path, motor_path)
    if warnings is not None:
        warnings += base.profile.warnings
    if loaded is not None:
        loaded.append(base.profile)
    texts, seed, _ = materialise(base, [], {}, seed)
    return Run(index=index, values={}, seed=seed, texts=texts, key=run_key(texts, seed))
