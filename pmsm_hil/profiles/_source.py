"""YAML sources with line numbers, and the one-line problem reports that name file, line and field.

Every YAML file (profile, motor, rig) is read once with ``yaml.compose`` so that each key path keeps
the line it was written on; the constructed data then goes through pydantic, and every pydantic or
semantic problem is reported as ``file:line: field.path = value message``.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Any

import yaml

__all__ = ["Problem", "ProfileError", "Source", "fmt_value", "loc_str", "read_source", "unit_of"]


# ----------------------------------------------------------------------------------- problems

_NO_VALUE = object()  # a problem about a key that has no value (missing, file-level)


@dataclass(frozen=True)
class Problem:
    """One problem found in one file: ``file:line[:column]: field = value message``."""

    file: str
    line: int | None
    field: str | None
    value: Any
    message: str
    column: int | None = None
    has_value: bool = True

    def __str__(self) -> str:
        where = self.file
        if self.line is not None:
            where += f":{self.line}"
            if self.column is not None:
                where += f":{self.column}"
        if self.field and self.has_value:
            body = f"{self.field} = {fmt_value(self.value)} {self.message}"
        elif self.field:
            body = f"{self.field} {self.message}"
        else:
            body = self.message
        return f"{where}: {body}"


class ProfileError(Exception):
    """A profile, motor or rig file is invalid.

    ``file``, ``line``, ``field`` and ``value`` describe the first problem; ``problems`` holds all
    of them and ``str()`` lists them one per line.
    """

    def __init__(self, problems: list[Problem] | Problem, warnings: list[str] | None = None):
        if isinstance(problems, Problem):
            problems = [problems]
        if not problems:
            raise ValueError("ProfileError needs at least one problem")
        self.problems: list[Problem] = list(problems)
        # what the file would be warned of once valid (e.g. an overloaded link), listed after the
        # problems so that one pass over the file finds both
        self.warnings: list[str] = list(warnings or [])
        first = self.problems[0]
        self.file: str = first.file
        self.line: int | None = first.line
        self.field: str | None = first.field
        self.value: Any = first.value if first.has_value else None
        super().__init__(str(self))

    def __str__(self) -> str:
        return "\n".join(
            [*(str(p) for p in self.problems), *(f"warning: {w}" for w in self.warnings)]
        )


# ----------------------------------------------------------------------------------- formatting

_UNITS = (  # longest suffix first
    ("_a_per_rad_s", "A/(rad/s)"),
    ("_a_per_rad", "A/rad"),
    ("_rpm_s", "r/min/s"),
    ("_rad_s", "rad/s"),
    ("_rpm", "r/min"),
    ("_nms", "N m s/rad"),
    ("_nm", "N m"),
    ("_kgm2", "kg m^2"),
    ("_ohm", "ohm"),
    ("_wb", "Wb"),
    ("_hz", "Hz"),
    ("_rad", "rad"),
    ("_s", "s"),
    ("_a", "A"),
    ("_v", "V"),
    ("_h", "H"),
    ("_c", "degC"),
)


def unit_of(name: str) -> str:
    """The unit that a name's suffix carries (``ts_s`` -> ``s``), or ``''``."""
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return unit
    return ""


def fmt_num(x: float | int) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float) and math.isfinite(x) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return f"{x:.6g}" if isinstance(x, float) else str(x)


def fmt_value(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, (bool, int, float)):
        return fmt_num(v)
    if isinstance(v, str):
        return repr(v)
    text = yaml.safe_dump(v, default_flow_style=True, width=1_000_000).strip()
    if len(text) <= 60:
        return text
    return f"[{len(v)} items]" if isinstance(v, list) else text[:57] + "..."


def loc_str(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


# ----------------------------------------------------------------------------------- YAML reading


class _Loader(yaml.SafeLoader):
    """SafeLoader that also reads YAML 1.2 floats without a dot (``50e-6``) as floats."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


@dataclass
class Source:
    """One YAML file: its text, data and the line of every key path."""

    path: str
    text: str = ""
    data: Any = None
    lines: dict[tuple, int] = dc_field(default_factory=dict)
    problems: list[Problem] = dc_field(default_factory=list)  # fatal: nothing more can be checked
    soft: list[Problem] = dc_field(default_factory=list)  # reported, but checking goes on

    def line(self, loc: tuple) -> int | None:
        """Line of ``loc``, else of its nearest ancestor that is in the file."""
        loc = tuple(loc)
        while True:
            if loc in self.lines:
                return self.lines[loc]
            if not loc:
                return None
            loc = loc[:-1]

    def has(self, loc: tuple) -> bool:
        return tuple(loc) in self.lines

    def problem(self, loc: tuple, message: str, value: Any = _NO_VALUE) -> Problem:
        return Problem(
            self.path,
            self.line(loc),
            loc_str(loc) or None,
            None if value is _NO_VALUE else value,
            message,
            has_value=value is not _NO_VALUE,
        )


MAX_NODES = 100_000  # a profile has a few hundred; aliases may not expand beyond this


def expanded_size(node: yaml.Node) -> int:
    """Nodes of the document with every alias expanded (memoised: linear in the distinct nodes),
    so an alias bomb is measured before anything expands it."""
    memo: dict[int, int] = {}

    def size(n: yaml.Node) -> int:
        if id(n) in memo:
            return memo[id(n)]
        memo[id(n)] = 1  # a recursive alias counts once
        if isinstance(n, yaml.MappingNode):
            total = 1 + sum(size(k) + size(v) for k, v in n.value)
        elif isinstance(n, yaml.SequenceNode):
            total = 1 + sum(size(v) for v in n.value)
        else:
            total = 1
        memo[id(n)] = min(total, 1 << 62)
        return memo[id(n)]

    return size(node)


def _walk(node: yaml.Node, path: tuple, src: Source) -> None:
    if isinstance(node, yaml.MappingNode):
        seen: dict[Any, int] = {}
        for key_node, val_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode):
                continue
            key = key_node.value
            key_line = key_node.start_mark.line + 1
            if key in seen:
                src.soft.append(
                    Problem(
                        src.path,
                        key_line,
                        loc_str((*path, key)),
                        None,
                        f"is given twice (first on line {seen[key]})",
                        has_value=False,
                    )
                )
                continue
            seen[key] = key_line
            if isinstance(val_node, yaml.ScalarNode):
                src.lines[(*path, key)] = val_node.start_mark.line + 1
                _yaml11_bool(val_node, (*path, key), src)
            else:
                src.lines[(*path, key)] = key_line
            _walk(val_node, (*path, key), src)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            src.lines[(*path, i)] = item.start_mark.line + 1
            if isinstance(item, yaml.ScalarNode):
                _yaml11_bool(item, (*path, i), src)
            _walk(item, (*path, i), src)


_BOOL_TAG = "tag:yaml.org,2002:bool"


def _yaml11_bool(node: yaml.ScalarNode, path: tuple, src: Source) -> None:
    """`yes`, `no`, `on`, `off` are true and false to YAML 1.1 (the loader's) and text to YAML
    1.2 (what most editors and other tools read): refused, so that a file means one thing."""
    if node.tag == _BOOL_TAG and node.value.lower() not in ("true", "false"):
        src.soft.append(
            Problem(
                src.path,
                node.start_mark.line + 1,
                loc_str(path),
                node.value,
                f"is {'true' if node.value.lower() in ('yes', 'on', 'y') else 'false'} to this "
                "reader (YAML 1.1) and text "
                "to YAML 1.2: write true or false",
            )
        )


def _bracket_hint(text: str, mark: Any, e: yaml.MarkedYAMLError) -> str:
    """A field path with an index (``profile.segments[1].load_nm``) written unquoted inside
    ``{...}``: YAML reads its ``[`` as a list. Say to quote it."""
    if mark is None or "'['" not in (e.problem or "") or "flow mapping" not in (e.context or ""):
        return ""
    lines = text.splitlines()
    line = lines[mark.line] if mark.line < len(lines) else ""
    m = re.search(r"([A-Za-z_][\w.]*\[\d+\][\w.\[\]]*)", line)
    if m is None:
        return ""
    return f"; quote a field with an index inside {{...}}: '{m.group(1)}'"


# the loaders' `what` and the shipped files' kind (pmsm_hil.profiles.shipped)
_SHIPPED_KIND = {
    "profile": "profile",
    "motor file": "motor",
    "rig file": "rig",
    "sweep file": "sweep",
}


def _shipped_hint(path: str, what: str) -> str:
    """For a loader given a path to nothing whose name is a shipped file's (`load_profile
    ("paper-a")` in a script: the CLI finds shipped files by name, the loaders take paths only),
    how to get the shipped file's path; else ""."""
    kind = _SHIPPED_KIND.get(what)
    if kind is None:
        return ""
    from .shipped import _shipped_named

    name = os.path.basename(path)
    found = _shipped_named(name, kind)
    if found is None or os.path.abspath(found) == os.path.abspath(path):
        return ""
    stem = found.stem
    return (
        f"; {stem!r} is a shipped {kind}: its path is "
        f"`pmsm_hil.profiles.shipped.resolve({stem!r}, {kind!r})`"
    )


def _not_utf8(path: str, raw: bytes, e: UnicodeDecodeError) -> Problem:
    """The octet that is not UTF-8, at its line and column (a file saved as Latin-1 or
    Windows-1252: a degree sign, a mu, an umlaut in a comment or a name)."""
    from pmsm_hil.files import octet_position

    line, column = octet_position(raw, e.start)
    text = raw[: e.start].rsplit(b"\n", 1)[-1].decode("utf-8", "replace")
    return Problem(
        path,
        line,
        None,
        None,
        f"is not UTF-8 text: octet 0x{raw[e.start]:02x} after {text[-20:]!r} ({e.reason}); "
        "save the file as UTF-8",
        column=column,
        has_value=False,
    )


def read_source(
    path: str,
    *,
    what: str = "file",
    referenced_by: tuple[Source, tuple, Any] | None = None,
    hint: str = "",
) -> Source:
    """Read and parse one YAML file; problems (unreadable, invalid YAML) go to ``src.problems``.

    ``referenced_by`` = (source, loc, value) of the key that named this file, so that a file that
    cannot be read is reported at that key, with ``hint`` after the reason.
    """
    src = Source(path=path)
    try:
        with open(path, "rb") as f:
            raw = f.read()
        src.text = raw.decode("utf-8")
    except OSError as e:
        reason = e.strerror or str(e)
        if referenced_by is not None:
            ref, loc, value = referenced_by
            src.problems.append(
                ref.problem(
                    loc, f"names a {what} that cannot be read: {path}: {reason}{hint}", value
                )
            )
        else:
            hint = _shipped_hint(path, what) if isinstance(e, FileNotFoundError) else ""
            src.problems.append(
                Problem(
                    path,
                    None,
                    None,
                    None,
                    f"cannot read the {what}: {reason}{hint}",
                    has_value=False,
                )
            )
        return src
    except UnicodeDecodeError as e:
        src.problems.append(_not_utf8(path, raw, e))
        return src

    loader = _Loader(src.text)
    try:
        node = loader.get_single_node()
        if node is not None and expanded_size(node) > MAX_NODES:
            src.problems.append(
                Problem(
                    path,
                    None,
                    None,
                    None,
                    f"is too large: its YAML aliases expand to more than "
                    f"{MAX_NODES} values (an alias bomb?)",
                    has_value=False,
                )
            )
            return src
        data = loader.construct_document(node) if node is not None else None
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        msg = "invalid YAML: " + (e.problem or "syntax error")
        if e.context:
            msg += f" ({e.context}"
            if e.context_mark is not None and e.context_mark is not mark:
                msg += f" on line {e.context_mark.line + 1}"
            msg += ")"
        msg += _bracket_hint(src.text, mark, e)
        if "'\\t'" in (e.problem or ""):  # YAML takes no tab where it reads indentation
            msg += "; YAML takes no tab there: replace it with spaces"
        src.problems.append(
            Problem(
                path,
                mark.line + 1 if mark else None,
                None,
                None,
                msg,
                column=mark.column + 1 if mark else None,
                has_value=False,
            )
        )
        return src
    except yaml.YAMLError as e:
        src.problems.append(Problem(path, None, None, None, f"invalid YAML: {e}", has_value=False))
        return src
    finally:
        loader.dispose()

    if node is None:
        src.problems.append(Problem(path, 1, None, None, f"the {what} is empty", has_value=False))
        return src
    if not isinstance(data, dict):
        src.problems.append(
            Problem(
                path,
                node.start_mark.line + 1,
                None,
                None,
                f"the {what} must be a mapping of `key: value` lines, not a {type(data).__name__}",
                has_value=False,
            )
        )
        return src
    src.data = data
    src.lines[()] = node.start_mark.line + 1
    _walk(node, (), src)
    return src


# ----------------------------------------------------------------------------------- pydantic -> problems


def resolve_ref(base_file: str, ref: str) -> str:
    """A path written in a YAML file, relative to that file's directory."""
    ref = os.path.expanduser(ref)
    if os.path.isabs(ref):
        return os.path.normpath(ref)
    return os.path.normpath(os.path.join(os.path.dirname(base_file), ref))
