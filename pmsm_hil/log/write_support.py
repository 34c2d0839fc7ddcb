"""What the log writer needs besides the records: the compressions this installation offers,
holding SIGINT/SIGTERM/SIGHUP back while a chunk or the summary goes to disk, and the error it
raises when the file cannot be written (pmsm_hil.log.writer)."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator

__all__ = [
    "HELD_SIGNALS",
    "LogWriteError",
    "available_compressions",
    "check_compression",
    "signals_held",
]


def available_compressions() -> list[str]:
    """The chunk compressions installed ("" = none, always)."""
    out = []
    import importlib.util

    if importlib.util.find_spec("zstandard") is not None:
        out.append("zstd")
    if importlib.util.find_spec("lz4") is not None:
        out.append("lz4")
    return [*out, ""]


def check_compression(name: str) -> None:
    """A clear error for a compression that is not installed."""
    if name not in available_compressions():
        raise ValueError(f"compression {name!r}: choose one of {available_compressions()}")


HELD_SIGNALS = {s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s}


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold SIGINT/SIGTERM/SIGHUP back while a chunk or the summary is written (POSIX)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    state, old = "before", set()
    try:
        try:
            old = signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS)
            state = "held"
        except (OSError, ValueError):
            state = "free"
        yield
    finally:
        if state == "held":
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        elif state == "before":
            # a signal that was already pending raised between the block and its record: the
            # mask must not stay blocked (a child process would inherit it and never see SIGINT)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, HELD_SIGNALS)


class LogWriteError(OSError):
    """The log file cannot be written (a full disk, a file size limit, an I/O error). The file
    keeps every chunk written before (``disk_t_s``: device time of the last message on disk);
    the writer writes nothing more and ``close()`` only releases the file."""

    def __init__(self, path: str, err: OSError, octets: int, disk_t_s: float | None):
        self.path, self.octets, self.disk_t_s = path, octets, disk_t_s
        upto = f"up to t = {disk_t_s:.3f} s" if disk_t_s is not None else "no messages"
        super().__init__(
            err.errno,
            f"cannot write the log {path}: {err.strerror or err} after {octets} octets; "
            f"the file holds the messages {upto}",
        )
