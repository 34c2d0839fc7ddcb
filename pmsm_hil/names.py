"""Did-you-mean: the one matcher behind every suggestion the tool makes for a name that names
nothing (a field of a profile, motor, rig or sweep file, a shipped file, a segment, a `gap`
action). It depends on nothing of the project.

A name is compared without case and separators first (``Paper-A``, ``labtypical``, ``speedRpm``
find ``paper-a``, ``lab-typical``, ``speed_rpm``), then as the beginning of names (``sew``:
``sew-cm3c80s``; ``speed``: several, all given, none being likelier than another), then by
spelling (difflib's ratio, 0.6 or more, on the names without case and separators)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

CUTOFF = 0.6  # difflib's ratio for a misspelling
MIN_PREFIX = 3  # shorter beginnings suggest nothing by themselves (``s``, ``sp``)
MAX_SHOWN = 6  # more beginnings than this: the name is too short to say which


def _key(name: str) -> str:
    return "".join(c for c in name.lower() if c.isalnum())


def same_name(name: str, known: Iterable[str]) -> str | None:
    """The known name written like ``name`` but for case and separators (``labtypical``:
    ``lab-typical``), or None."""
    want = _key(name)
    return next((n for n in known if isinstance(n, str) and want and _key(n) == want), None)


def closest(name: str, known: Iterable[str]) -> list[str]:
    """The known names that ``name`` was likely meant to be, in ``known``'s order: one written
    alike but for case and separators; else the names it begins (up to MAX_SHOWN); else the
    nearest by spelling. Empty when none is close."""
    names = list(dict.fromkeys(n for n in known if isinstance(n, str)))
    want = _key(name)
    if not want:
        return []
    same = [n for n in names if _key(n) == want]
    if same:
        return same[:1]
    if len(want) >= MIN_PREFIX:
        begun = [n for n in names if _key(n).startswith(want)]
        if len(begun) > MAX_SHOWN:  # one of them by spelling would be a guess
            return []
        if begun:
            return begun
    keys: dict[str, str] = {}
    for n in names:
        keys.setdefault(_key(n), n)
    return [keys[k] for k in difflib.get_close_matches(want, list(keys), n=1, cutoff=CUTOFF)]


def did_you_mean(name: str, known: Iterable[str], what: str = "") -> str:
    """``"; did you mean 'x'?"`` (``what`` before the name: ``"the shipped motor "``), ``"; did
    you mean one of 'x', 'y'?"``, or ``""`` when nothing is close."""
    close = closest(name, known)
    if not close:
        return ""
    if len(close) == 1:
        return f"; did you mean {what}{close[0]!r}?"
    return f"; did you mean one of {', '.join(map(repr, close))}?"


__all__ = ["closest", "did_you_mean", "same_name"]
