"""A user's file written whole or not at all: the text goes to a temporary file beside it, which
then replaces it in one step (``os.replace``). A Ctrl-C, a full disk or a killed process while it
is written leaves the file as it was (a commissioned motor file, rewritten with its flux map, was
a plain write: an interruption there could leave it cut); and where in a user's file an octet is
(the line and column an error names). It depends on nothing of the project."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_text_whole(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all; raises OSError as ``write_text``
    would, leaving ``path`` as it was and no temporary file behind."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        if path.exists():  # keep the permissions the user gave the file
            os.chmod(tmp, path.stat().st_mode & 0o7777)
        else:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


__all__ = ["write_text_whole"]


def octet_position(raw: bytes, offset: int) -> tuple[int, int]:
    """The line and the column (both from 1, the column in octets) of the octet at ``offset`` of
    a file's contents ``raw``: where a byte that is not UTF-8 stands, for the error naming it."""
    line = raw.count(b"\n", 0, offset) + 1
    return line, offset - (raw.rfind(b"\n", 0, offset) + 1) + 1
