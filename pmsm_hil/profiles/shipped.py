"""The shipped profiles, motor, rig and flux-map files, and how a bare name finds them.

The files live in the repository's `profiles/` folder, which is installed as the package data of
`pmsm_hil.shipped` (setup.py), so an installed pmsm-hil finds them from any directory; the
repository's `sweeps/` folder likewise, as `pmsm_hil.shipped.sweeps`:

    resolve("paper-a", "profile")        -> .../shipped/paper-a.yaml
    resolve("lab-typical", "rig")        -> .../shipped/rigs/lab-typical.yaml
    resolve("tolerance", "sweep")        -> .../shipped/sweeps/tolerance.yaml
    resolve("my/own.yaml", "profile")    -> my/own.yaml   (a path that exists always wins)

A file that names another (a profile its motor and rig, a motor or rig its flux map) names it by a
path relative to itself; where nothing is there, the shipped file of that kind and name is taken
(`in_file`), so a shipped profile copied to a folder of one's own still runs, and `motor:
paper-a-ipmsm` works as on the command line.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from pmsm_hil.names import did_you_mean, same_name

from ._source import Problem, ProfileError

# kind -> sub-folder of the shipped tree and the files' suffix
KINDS = {
    "profile": ("", ".yaml"),
    "motor": ("motors", ".yaml"),
    "rig": ("rigs", ".yaml"),
    "map": ("maps", ".csv"),
    "sweep": ("", ".yaml"),  # in the sweeps root (sweeps_root), not the profiles'
}


def package_dir(package: str) -> Path | None:
    """The folder of an installed data package of pmsm-hil (`pmsm_hil.shipped`, `pmsm_hil.proto`),
    or None when it is not installed (the source tree: the caller knows its folder there)."""
    try:
        spec = importlib.util.find_spec(package)
    except ImportError:
        return None
    for loc in (spec.submodule_search_locations or []) if spec else []:
        if os.path.isdir(loc):
            return Path(loc)
    return None


def shipped_root() -> Path:
    """The folder of the shipped files (installed package data, or the source tree's profiles/)."""
    return package_dir("pmsm_hil.shipped") or Path(__file__).resolve().parents[2] / "profiles"


def sweeps_root() -> Path:
    """The folder of the shipped sweep files (installed package data, or the source tree's
    sweeps/)."""
    return package_dir("pmsm_hil.shipped.sweeps") or Path(__file__).resolve().parents[2] / "sweeps"


def _root(kind: str) -> Path:
    return sweeps_root() if kind == "sweep" else shipped_root()


def shipped_file(rel: str) -> str:
    """A shipped file by its path in the shipped tree, e.g. "rigs/default.yaml"."""
    return str(shipped_root() / rel)


def shipped(kind: str) -> list[Path]:
    """The shipped files of one kind, sorted by name."""
    sub, suffix = KINDS[kind]
    folder = _root(kind) / sub
    return sorted(p for p in folder.glob(f"*{suffix}") if p.is_file())


def resolve(name: str | os.PathLike, kind: str) -> str:
    """A path given by the user, or the shipped file of that kind and name.

    An existing file wins; otherwise a bare name (no folder), with or without its suffix, is looked
    up among the shipped files. A path to no file whose name is a shipped file's (e.g. the
    repository's ``profiles/paper-a.yaml`` from another directory) is an error that gives the bare
    name. Anything else is returned unchanged, so the loader reports it.
    """
    text = os.fspath(name)
    if os.path.isfile(text):
        return text
    if os.sep not in text and "/" not in text:
        candidate = _shipped_named(text, kind)
        if candidate is not None:
            return str(candidate)
        stems = [p.stem for p in shipped(kind)]
        bare = text.removesuffix(KINDS[kind][1])
        near = did_you_mean(bare, stems)  # written otherwise, a beginning, or misspelt
        # one of this kind written otherwise comes before one of another kind of that name
        hint = near if same_name(bare, stems) else (_other_kind(text, kind) or near)
        raise _not_found(
            text,
            f"is neither a file nor a shipped {kind}{hint} (shipped: {', '.join(stems)}; "
            "`pmsm-hil profiles` lists them)",
        )
    shipped_one = _shipped_named(os.path.basename(text), kind)
    if shipped_one is not None and not os.path.exists(text):
        raise _not_found(
            text,
            f"no such file; the shipped {kind} of that name is found from any directory by its "
            f"bare name: {shipped_one.stem}",
        )
    return text


# where a shipped file of each kind is given (for a name given where another kind is wanted)
_USE = {
    "profile": "a profile: `pmsm-hil run {n}`",
    "motor": "a motor: `--motor {n}`",
    "rig": "a rig: `--rig {n}`",
    "map": "a flux map: a motor file's `flux_map` or a rig's saturation `map`",
    "sweep": "a sweep: `pmsm-hil sweep {n}`",
}


def _other_kind(name: str, kind: str) -> str:
    """'; NAME is a shipped sweep: ...' when a shipped file of another kind has that name, also
    written otherwise (`labtypical` for the rig lab-typical)."""
    for other, use in _USE.items():
        if other == kind:
            continue
        alike = same_name(name.removesuffix(KINDS[other][1]), [p.stem for p in shipped(other)])
        if alike:
            return f"; {alike!r} is {use.format(n=alike)}"
    return ""


def _not_found(text: str, why: str) -> ProfileError:
    """The error of a name or path that finds no file: the name and what to give instead."""
    return ProfileError(Problem(text, None, None, None, why, has_value=False))


def in_file(path: str, ref: str, kind: str) -> tuple[str, str | None]:
    """The file that ``ref`` (written in a file, already resolved against it: ``path``) names: the
    path itself if there is a file there, else the shipped file of that kind with the same name,
    with a note that says so; else the path (its loader reports it)."""
    if os.path.exists(path):
        return path, None
    candidate = _shipped_named(os.path.basename(ref), kind)
    if candidate is not None:
        if os.sep not in ref and "/" not in ref and not ref.endswith(KINDS[kind][1]):
            return str(candidate), None  # a bare shipped name, as the docs write them: no note
        return str(candidate), f"nothing at {path}: the shipped {kind} {candidate.stem!r} is used"
    return path, None


def near_name(ref: str, kind: str) -> str:
    """For a motor or rig name in a file that finds nothing: the shipped one it was likely meant
    to be, or the shipped names (appended to the file's "cannot be read")."""
    names = [p.stem for p in shipped(kind)]
    stem = os.path.basename(ref).removesuffix(KINDS[kind][1])
    return did_you_mean(stem, names, f"the shipped {kind} ") or (
        f" (shipped {kind}s: {', '.join(names)})"
    )


def _shipped_named(name: str, kind: str) -> Path | None:
    """The shipped file of that kind called ``name`` (with or without its suffix), or None."""
    sub, suffix = KINDS[kind]
    stem = name[: -len(suffix)] if name.endswith(suffix) else name
    candidate = _root(kind) / sub / f"{stem}{suffix}"
    return candidate if stem and candidate.is_file() else None
