"""The files a command writes, checked before anything runs: a wrong name or a place that cannot
be written is an error naming the option (exit 2), not a traceback after the work."""

from __future__ import annotations

import os
from pathlib import Path

from pmsm_hil.cli.errors import fail


def write_problem(path: Path, option: str, overwrite: bool = True) -> str | None:
    """Why ``path`` cannot be written, or None. The check opens the file for appending: an
    existing file is left as it was, one made by the check is removed again. Without
    ``overwrite`` a file already there is refused (another run's log), as `run --out` does."""
    existed = path.exists() or path.is_symlink()
    if existed and not overwrite:
        return (
            f"{option} {path}: a file is there already; --overwrite replaces it "
            "(or give another name)"
        )
    try:
        with open(path, "ab"):
            pass
    except OSError as e:
        return f"{option} {path}: cannot write there ({e.strerror or e})"
    if not existed:
        path.unlink(missing_ok=True)
    return None


def check_output(
    path: Path, option: str, suffixes: tuple[str, ...], kind: str, overwrite: bool = True
) -> int | None:
    """None when ``path`` ends in one of ``suffixes`` and can be written there (its folder is
    made; write_problem, ``overwrite`` as there); else the error is reported and 2 returned.
    ``kind`` says what the file is, e.g. "the log is MCAP"."""
    if path.suffix not in suffixes:
        names = " or ".join(f"*{s}" for s in suffixes)
        return fail("error", f"{option} {path}: {kind}, name it {names}", 2)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return fail("error", f"{option} {path}: cannot write there ({e.strerror or e})", 2)
    why = write_problem(path, option, overwrite)
    return fail("error", why, 2) if why else None


def folder_problem(path: Path) -> str | None:
    """Why ``path`` cannot be an output folder (logs, a results table), or None; the folder is made
    if missing. A file there is not taken for a scheduler that cannot be reached (Dask starts
    before the folder is written)."""
    if path.exists() and not path.is_dir():
        return "is a file; give a folder"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return f"cannot make the folder ({e.strerror or e})"
    if not os.access(path, os.W_OK):
        return "the folder is not writable"
    return None
