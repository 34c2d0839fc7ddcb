"""The files a command writes, checked before anything runs: a wrong name or a place that cannot
be written is an error naming the option (exit 2), not a traceback after the work."""

from __future__ import annotations

from pathlib import Path

from pmsm_hil.cli.errors import fail


def check_output(path: Path, option: str, suffixes: tuple[str, ...], kind: str) -> int | None:
    """None when ``path`` ends in one of ``suffixes`` and can be written there (its folder is
    made); else the error is reported and 2 returned. ``kind`` says what the file is, e.g. "the
    log is MCAP". The check opens the file for appending: an existing file is left as it was, one
    made by the check is removed again."""
    if path.suffix not in suffixes:
        names = " or ".join(f"*{s}" for s in suffixes)
        return fail("error", f"{option} {path}: {kind}, name it {names}", 2)
    existed = path.exists() or path.is_symlink()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "ab"):
            pass
    except OSError as e:
        return fail("error", f"{option} {path}: cannot write there ({e.strerror or e})", 2)
    if not existed:
        path.unlink(missing_ok=True)
    return None
