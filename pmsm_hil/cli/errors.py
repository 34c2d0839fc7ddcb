"""How the CLI reports errors: one clear line, no traceback for a user or device error."""

from __future__ import annotations

import sys
from functools import cache
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console


@cache
def err_console() -> Console:
    """The console on stderr, made at the first report (rich is not imported before: a command
    that reports nothing does not wait for it)."""
    from rich.console import Console

    # no emoji codes (":x" in a CAN spec is text) and no markup from the message itself
    return Console(stderr=True, highlight=False, emoji=False)


def report(kind: str, message: str) -> None:
    from rich.markup import escape

    err_console().print(f"[bold red]{kind}:[/] {escape(message)}", soft_wrap=True)


def fail(kind: str, message: str, code: int) -> int:
    report(kind, message)
    sys.stderr.flush()
    return code
