"""pmsm-hil command line: one module per subcommand, each thin over the library."""

from __future__ import annotations

import argparse
import os
import signal
import sys

# A command's large arrays (a log's columns) are filled once and soon freed: numpy's default
# madvise(MADV_HUGEPAGE) makes the kernel compact memory for huge pages at their first touch,
# which costs more than the pages save (`analyze` of a one-hour log: 0.7 s more system time on
# the project's machine, docs/performance.md). Read by numpy when it is imported, so set before that;
# a value in the environment wins.
os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")
# pydantic looks for plugins among every installed package's entry points when it builds its first
# validator (some 10 ms at each start in a venv of this project's size); the CLI uses none. A value
# in the environment wins, as above.
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")

from pmsm_hil import __version__
from pmsm_hil.cli import (
    analyze,
    bench,
    check,
    commission,
    emulate,
    gap,
    import_csv,
    log,
    profiles,
    report,
    run,
    sweep,
    test,
)
from pmsm_hil.transport import quiet_python_can

COMMANDS = {
    "run": run,
    "check": check,
    "commission": commission,
    "emulate": emulate,
    "analyze": analyze,
    "report": report,
    "bench": bench,
    "profiles": profiles,
    "log": log,
    "sweep": sweep,
    "test": test,
    "import": import_csv,
    "gap": gap,
}

EXIT_USER_ERROR = 2  # bad input: profile, file, option
EXIT_DEVICE_ERROR = 3  # link or device: no answer, mismatch, dropped link, fault


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pmsm-hil",
        description="Hardware-in-the-loop tool for PMSM drives: runs speed/load profiles on an "
        "F28335 rig or its emulator, logs to MCAP, analyses logs.",
    )
    p.add_argument("--version", action="version", version=f"pmsm-hil {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for _name, mod in COMMANDS.items():
        mod.add_parser(sub)
    return p


def _terms_as_interrupts() -> dict[int, object]:
    """SIGTERM and SIGHUP (a `kill`, a job's time limit, a closed terminal) raise
    KeyboardInterrupt as a Ctrl-C does, from the command's first line: every command then stops
    the motor, keeps its log or its sweep's table and exits 130 alike, where the default action
    ended the process with nothing written (`run`'s device opening, a whole `sweep`). `run`
    counts them itself while it streams (pmsm_hil.interrupts). Returns the handlers replaced."""
    import threading

    old: dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():
        for name in ("SIGTERM", "SIGHUP"):
            sig = getattr(signal, name, None)
            if sig is not None and signal.getsignal(sig) is signal.SIG_DFL:
                old[sig] = signal.signal(sig, signal.default_int_handler)
    return old


def main(argv: list[str] | None = None) -> int:
    if sweep.asks_report_help(sys.argv[1:] if argv is None else argv):
        sweep.report_parser().print_help()
        return 0
    args = build_parser().parse_args(argv)
    quiet_python_can()
    replaced = _terms_as_interrupts()
    try:
        code = COMMANDS[args.command].main(args)
    except KeyboardInterrupt:
        # Ctrl-C in a command without its own handling (run, sweep and commission stop the motor
        # or keep the journal and say so themselves): one line, not a traceback
        kept = ""
        if args.command == "bench" and getattr(args, "out", None):  # its trials are journalled
            kept = f"; the trials done are kept in {args.out}: the same command takes them up"
        print(f"pmsm-hil {args.command}: interrupted{kept}", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of our output went away (`| head`): the work itself has ended cleanly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:  # an in-process caller gets its handlers back
        for sig, handler in replaced.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
    _returned.append(args.command)
    return code


_returned: list[str] = []  # the commands whose main returned (not raised): for entry


def entry() -> int:
    """The `pmsm-hil` program: ``main``, then the process ends. Before it does, the objects alive
    are moved out of the garbage collector's reach (``gc.freeze``): the interpreter's last
    collections then skip them — a third of a second's run spent some 50 ms there walking the
    libraries' objects (pydantic's schemas, numpy) only to free them as the process ends.

    A command whose module sets ``ENDS_CLEAN`` closes its files, waits for its child processes
    and stops its threads itself: when it has returned and no thread is left that the
    interpreter would wait for (only daemon threads), the process
    ends at once (``os._exit``, after stdout and stderr are flushed) instead of tearing the
    interpreter down object by object (`run` of paper-a: 6-10 ms from its return to the
    process's end instead of 24-26 ms, docs/performance.md). Other commands (Dask clusters, temporary
    directories) keep the interpreter's ordinary exit, atexit handlers and all."""
    try:
        code = main()
    finally:
        import gc

        gc.freeze()
    if _returned and getattr(COMMANDS[_returned[-1]], "ENDS_CLEAN", False):
        import threading

        main_thread = threading.main_thread()
        # a daemon thread ends with the process either way; any other the interpreter waits for
        if all(t is main_thread or t.daemon for t in threading.enumerate()):
            try:
                sys.stdout.flush()
                sys.stderr.flush()
            except (OSError, ValueError):  # a reader gone: the ordinary exit reports as before
                return code
            os._exit(code)
    return code


if __name__ == "__main__":
    sys.exit(entry())
