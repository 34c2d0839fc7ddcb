"""pydantic's validation errors in the profiles' words: one problem per field at the file's line,
the field's range and unit, one message for a value that fits no member of a union (the files'
loader is pmsm_hil.profiles._source)."""

from __future__ import annotations

import re
import types
import typing
from typing import Any

import annotated_types
from pydantic import BaseModel, ValidationError

from pmsm_hil.names import did_you_mean

from ._source import Problem, Source, fmt_num, loc_str, unit_of


def _unwrap(annotation: Any) -> Any:
    """Optional[X] -> X, list[X] -> list marker handled by caller."""
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return _unwrap(args[0])
    return annotation


def resolve_field(model: type[BaseModel], loc: tuple) -> tuple[type[BaseModel] | None, Any]:
    """Walk ``loc`` through ``model``; return (model owning the last key, its FieldInfo or None)."""
    current: Any = model
    owner: type[BaseModel] | None = None
    info = None
    for part in loc:
        current = _unwrap(current)
        if isinstance(part, int):
            if typing.get_origin(current) in (list, tuple):
                current = typing.get_args(current)[0]
                continue
            return None, None
        if isinstance(current, type) and issubclass(current, BaseModel):
            owner = current
            info = current.model_fields.get(part)
            if info is None:
                return owner, None
            current = info.annotation
        else:
            return None, None
    return owner, info


def range_text(info: Any, name: str) -> str:
    lo: Any = None
    hi: Any = None
    lo_open = hi_open = False
    for m in getattr(info, "metadata", ()):
        if isinstance(m, annotated_types.Gt):
            lo, lo_open = m.gt, True
        elif isinstance(m, annotated_types.Ge):
            lo, lo_open = m.ge, False
        elif isinstance(m, annotated_types.Lt):
            hi, hi_open = m.lt, True
        elif isinstance(m, annotated_types.Le):
            hi, hi_open = m.le, False
    unit = unit_of(name)
    unit = f" {unit}" if unit else ""
    if lo is not None and hi is not None:
        return (
            f"is outside the allowed range {'(' if lo_open else '['}{fmt_num(lo)}, "
            f"{fmt_num(hi)}{')' if hi_open else ']'}{unit}"
        )
    if lo is not None:
        return f"must be {'>' if lo_open else '>='} {fmt_num(lo)}{unit}"
    if hi is not None:
        return f"must be {'<' if hi_open else '<='} {fmt_num(hi)}{unit}"
    return "is out of range"


# pydantic error types whose message in the profiles' words does not depend on the error
_MESSAGES = {
    **dict.fromkeys(("int_type", "int_parsing", "int_from_float"), "is not a whole number"),
    **dict.fromkeys(("bool_type", "bool_parsing"), "is not true or false"),
    "string_type": "is not text (put it in quotes)",
    "finite_number": "is not a finite number",
    **dict.fromkeys(
        ("model_type", "model_attributes_type", "dict_type"),
        "must be a mapping of `key: value` lines",
    ),
    "list_type": "must be a list (lines starting with `- `)",
    "string_too_short": "must not be empty",
}
_RANGE_TYPES = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")


def error_message(err: Any, info: Any, name: str) -> str:
    """The message of one pydantic error (not `missing` or `extra_forbidden`), in the profiles'
    words: ``info`` is the field's FieldInfo (for its range), ``name`` its key (for the unit)."""
    typ = err["type"]
    ctx = err.get("ctx", {})
    if typ in _MESSAGES:
        return _MESSAGES[typ]
    if typ in ("float_type", "float_parsing"):
        return "is not a number" + _number_hint(err.get("input"))
    if typ in _RANGE_TYPES:
        text = range_text(info, name)
        ops = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}
        for k, op in ops.items():  # a union member's own bound (the field's info has none)
            if text == "is out of range" and k in ctx:
                unit = unit_of(name)
                text = f"must be {op} {fmt_num(ctx[k])}" + (f" {unit}" if unit else "")
        return text
    if typ == "literal_error":
        return f"is not one of {ctx.get('expected', '')}"
    if typ == "too_short":
        return f"must have at least {ctx.get('min_length')} item(s)"
    if typ == "too_long":
        return f"must have at most {ctx.get('max_length')} items"
    return err["msg"][0].lower() + err["msg"][1:]


def _number_hint(value: Any) -> str:
    """What to change in a text where a number belongs: the quotes around a number, or the unit
    after one (the unit is in the field's name)."""
    if not isinstance(value, str):
        return ""
    try:
        float(value)
        return " (write numbers without quotes)"
    except ValueError:
        pass
    if re.match(r"\s*[-+]?(\d|\.\d)", value):
        return " (write the number alone: the unit is in the field's name)"
    return ""


_UNION_TAGS = {"float", "int", "bool", "str"}
_MEMBER_TAGS = _UNION_TAGS | {"constrained-float", "constrained-int", "constrained-str"}
# what a union member of each type error asks for (the alternatives of one message)
_WANTS = {
    "float_type": "a number",
    "float_parsing": "a number",
    "int_type": "a whole number",
    "int_parsing": "a whole number",
    "int_from_float": "a whole number",
    "string_type": "text",
    "bool_type": "true or false",
    "bool_parsing": "true or false",
}


def _member_tag(p: object) -> bool:
    return isinstance(p, str) and (p in _MEMBER_TAGS or p.startswith("literal["))


def _merged_unions(errors: Any, loc_prefix: tuple) -> list[tuple[tuple, dict]]:
    """(loc, error) per problem. Pydantic reports a value that fits no member of a union once per
    member (`segment.str`, `segment.int`; `speed_error_max_rpm.constrained-float`,
    `.literal['band']`): such errors become one, at the field — the member's own error when the
    value has a member's type but breaks its constraint (a bound <= 0), else one `type` error
    that lists what each member takes ("a number or 'band'"). A list item of a union (a sweep
    axis's values) keeps its first member's error, as before."""
    groups: dict[tuple, list[dict]] = {}
    order: list[tuple[tuple, dict | None]] = []  # (loc, the error itself unless a union's)
    for err in errors:
        loc = loc_prefix + tuple(p for p in err["loc"] if isinstance(p, (str, int)))
        if loc and _member_tag(loc[-1]):
            key = loc[:-1]
            if key not in groups:
                order.append((key, None))
            groups.setdefault(key, []).append(err)
        else:
            order.append((loc, err))
    out: list[tuple[tuple, dict]] = []
    for loc, single in order:
        if single is not None:
            out.append((loc, single))
            continue
        errs = groups[loc]
        if len(errs) == 1 or isinstance(loc[-1], int):
            out.append((loc, errs[0]))
            continue
        own = [e for e in errs if e["type"] not in _WANTS and e["type"] != "literal_error"]
        if own:
            out.append((loc, own[0]))
            continue
        wants = []
        for e in errs:
            w = (
                str(e.get("ctx", {}).get("expected", ""))
                if e["type"] == "literal_error"
                else _WANTS[e["type"]]
            )
            if w not in wants:
                wants.append(w)
        out.append((loc, {**errs[0], "type": "union_type", "wants": wants}))
    return out


def _not_a_setting(owner: type[BaseModel] | None, name: str) -> str:
    """Why a control key that an engineer may look for is not a setting ('' for other keys)."""
    if owner is None or owner.__name__ != "Control":
        return ""
    key = name.lower().replace("-", "_")
    if "delay" in key:
        return (
            "the one-period delay compensation is always on, in the MPCC and in FOC "
            "(docs/control.md, 'Delay compensation and the angles used')"
        )
    if key.startswith(("foc_k", "foc_gain", "current_k", "i_k")):
        return (
            "the FOC PI gains are designed from control.foc_bw_rad_s and the motor's L and R "
            "(kp = bw L, ki = bw R; docs/sensorless.md); set foc_bw_rad_s"
        )
    return ""


def validation_problems(
    exc: ValidationError, src: Source, model: type[BaseModel], loc_prefix: tuple = ()
) -> list[Problem]:
    out: list[Problem] = []
    for loc, err in _merged_unions(exc.errors(), loc_prefix):
        typ = err["type"]
        value = err.get("input")
        name = str(loc[-1]) if loc else ""
        owner, info = resolve_field(model, loc[len(loc_prefix) :]) if loc else (None, None)
        if typ == "missing":
            out.append(
                src.problem(
                    loc,
                    "is missing (required"
                    + (f": {info.description})" if info is not None and info.description else ")"),
                )
            )
            continue
        if typ == "extra_forbidden":
            allowed = list(owner.model_fields) if owner is not None else []
            hint = did_you_mean(str(name), allowed)
            section = loc_str(loc[:-1]) or "the file"
            why = _not_a_setting(owner, str(name))
            if why:
                msg = f"is not a field of {section}: {why}"
            elif hint:
                msg = f"is not a field of {section}{hint}"
            else:
                msg = f"is not a field of {section} (known: {', '.join(allowed)})"
            out.append(src.problem(loc, msg, value))
            continue
        if typ == "union_type":
            msg = "is not " + " or ".join(err["wants"])
            hint = _number_hint(value)
            if hint:
                msg += hint
            elif info is not None and info.description:
                msg += f" ({info.description})"
        else:
            msg = error_message(err, info, name)
        out.append(src.problem(loc, msg, value))
    return out
