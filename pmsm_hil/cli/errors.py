"""How the CLI reports errors: one clear line, no traceback for a user or device error."""

from __future__ import annotations

import sys
from functools import cache
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console

    from pmsm_hil.profiles import Profile
    from pmsm_hil.runner import RunResult


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


def device_ended_early(result: RunResult, profile: Profile | None, where: str) -> int | None:
    """Exit 4 with one line for a run the device ended before its profile's end: a fault (the
    motor file's limit it tripped, and the load-step hint when a step caused it) or another stop;
    ``where`` says what was kept ("see LOG"). None for a run that ended as planned."""
    if result.faults:
        from pmsm_hil.recorder import fault_limits_text, fault_text

        what = (
            fault_limits_text(result.faults, profile.motor)
            if profile is not None
            else fault_text(result.faults)
        )
        code = fail("fault", f"device faulted ({what}); {where}", 4)
        if profile is not None:
            from pmsm_hil.analysis.fault_hint import load_step_hint

            step_hint = load_step_hint(result.live.events, profile)
            if step_hint:
                print(f"hint: {step_hint}", file=sys.stderr)
        return code
    if result.stop_reason and result.stop_reason not in ("profile end", "host stop"):
        return fail("stopped", f"device stopped: {result.stop_reason}; {where}", 4)
    return None


# what reaching a Dask scheduler can raise: OSError, nothing answers; ValueError, not an address
# Dask knows (http://...); MemoryError, something answered that does not speak Dask's protocol
SCHEDULER_ERRORS = (OSError, ValueError, MemoryError)


def scheduler_failed(scheduler: str | None, e: BaseException) -> int:
    """The message and exit code 3 for ``e`` (one of SCHEDULER_ERRORS) met while running on
    ``scheduler``; re-raises an error that is not about reaching one (no scheduler given)."""
    if not scheduler and not isinstance(e, OSError):
        raise e
    why = str(e) if isinstance(e, OSError) else f"{type(e).__name__}: {e}"
    return fail(
        "error",
        f"cannot reach the scheduler {scheduler}: {why} (a Dask scheduler's address is "
        "tcp://HOST:8786; 8787 is its dashboard)",
        3,
    )
