"""How the CLI reports errors: one clear line, no traceback for a user or device error."""

from __future__ import annotations

import sys

from rich.console import Console
from rich.markup import escape

# no emoji codes (":x" in a CAN spec is text) and no markup from the message itself
err_console = Console(stderr=True, highlight=False, emoji=False)


def report(kind: str, message: str) -> None:
    err_console.print(f"[bold red]{kind}:[/] {escape(message)}", soft_wrap=True)


def fail(kind: str, message: str, code: int) -> int:
    report(kind, message)
    sys.stderr.flush()
    return code
