"""pytest plugin for HIL tests of your own (loaded by the `pytest11` entry point of pmsm-hil).

    HERE = Path(__file__).parent                   # a relative path is the working directory's

    def test_load_step_recovers(hil_device):
        run = hil_device.run(HERE / "my-drive.yaml")
        run.assert_accepted()                      # the profile's acceptance criteria
        assert run.summary.segments[2].recovery_s < 0.2

    @pytest.mark.hil_rig                           # a rig's path: skipped on the in-process emulator
    def test_on_the_bench(hil_device):
        hil_device.run("paper-a").assert_accepted()

Options: ``--hil-port=/dev/ttyUSB0`` (a rig on a serial port; one word, else pytest takes the
port for a test path when it looks for its ini file, and the plugin warns), ``--hil-can SPEC`` (a
rig on CAN, a python-can spec as for `pmsm-hil run --can`), else the in-process emulator;
``--hil-rig`` (a rig file or shipped name replacing each profile's, as `pmsm-hil run --rig`: on
the emulator its plant, on a real rig only what the firmware is configured from, the encoder's
counts), ``--hil-seed`` (the emulator's, default 1). They are checked once, when pytest starts
(`pytest_configure`): a bad one is a usage error naming the option (exit code 4), before any test
runs.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from pmsm_hil.analysis.identification import IdentTable
    from pmsm_hil.analysis.summary import RunSummary

__all__ = ["HilDevice", "HilRun"]


@dataclass
class HilRun:
    """One run: the profile, the runner's result, the log, and (lazily) its summary and checks."""

    profile: Any
    result: Any
    log_path: Path
    _summary: Any = field(default=None, repr=False)
    _checks: Any = field(default=None, repr=False)

    @property
    def summary(self) -> RunSummary:
        if self._summary is None:
            from pmsm_hil.analysis.summary import summarize_log

            self._summary = summarize_log(self.log_path)
        return self._summary

    def identification(self, t0_s: float | None = None, t1_s: float | None = None) -> IdentTable:
        """The identification table (default window: up to the first plant step)."""
        from pmsm_hil.analysis.identification import identification_table, identification_window

        w0, w1 = identification_window(self.profile)
        return identification_table(
            self.log_path, w0 if t0_s is None else t0_s, w1 if t1_s is None else t1_s
        )

    @property
    def checks(self) -> list:
        """The profile's acceptance criteria judged on this run (the default without a section:
        the whole profile played, no fault)."""
        if self._checks is None:
            from pmsm_hil.analysis.acceptance import evaluate
            from pmsm_hil.profiles.acceptance import Acceptance
            from pmsm_hil.sweep.suite import DEFAULT_ACCEPTANCE

            acc = self.profile.acceptance or Acceptance.model_validate(DEFAULT_ACCEPTANCE)
            wants_ident = acc.run is not None and acc.run.identification
            self._checks = evaluate(
                acc, self.summary, self.identification() if wants_ident else None
            )
        return self._checks

    @property
    def accepted(self) -> bool:
        return all(c.passed for c in self.checks)

    def assert_accepted(self) -> None:
        __tracebackhide__ = True  # pytest shows the user's line, not this one
        failed = [c for c in self.checks if not c.passed]
        if failed:
            lines = [
                f"{c.scope}: {c.criterion} measured {c.measured}, bound {c.bound}" for c in failed
            ]
            raise AssertionError(
                f"{self.profile.name}: {len(failed)} of {len(self.checks)} acceptance "
                f"checks failed (log {self.log_path}):\n  " + "\n  ".join(lines)
            )


class HilDevice:
    """The device the tests run on: the in-process emulator, or a rig on a serial port or CAN."""

    def __init__(
        self,
        port: str | None = None,
        can: str | None = None,
        rig: str | None = None,
        seed: int = 1,
        log_dir: Path | None = None,
    ):
        self.port, self.can, self.rig, self.seed = port, can, rig, seed
        self.log_dir = Path(log_dir) if log_dir is not None else Path.cwd()
        self._n = 0

    @property
    def kind(self) -> str:
        return "serial" if self.port else ("can" if self.can else "emulator")

    @property
    def is_rig(self) -> bool:
        return self.kind != "emulator"

    def _link(self, profile, seed: int):
        from pmsm_hil.device import DeviceSpec, open_device

        return open_device(DeviceSpec(port=self.port, can=self.can, seed=seed), profile)

    def run(
        self,
        profile: str | os.PathLike,
        out: str | os.PathLike | None = None,
        seed: int | None = None,
        rig: str | None = None,
    ) -> HilRun:
        """Run a profile (a path or a shipped name) to the end; the log goes to ``out`` (default: a
        numbered file in the session's log folder). A relative path is taken from the working
        directory pytest runs in, not the test file's folder: give ``Path(__file__).parent /
        "mine.yaml"`` for a profile beside the test.

        A bad profile (ProfileError), a link that cannot be opened or drops (TransportError) or a
        device that does not answer (DeviceError) is raised as itself, its message saying what
        and where, shown at the test's line without the frames of pmsm-hil and pyserial under it
        (hundreds of lines for a port that is not a serial port)."""
        from pmsm_hil.errors import DeviceError, TransportError
        from pmsm_hil.profiles import ProfileError

        __tracebackhide__ = True
        try:
            return self._run(profile, out, seed, rig)
        except (ProfileError, TransportError, DeviceError) as e:
            raise e.with_traceback(None) from None

    def _run(
        self,
        profile: str | os.PathLike,
        out: str | os.PathLike | None,
        seed: int | None,
        rig: str | None,
    ) -> HilRun:
        from pmsm_hil.profiles import load_profile
        from pmsm_hil.profiles.shipped import resolve
        from pmsm_hil.sweep.execute import run_in_process

        seed = self.seed if seed is None else seed
        rig = rig or self.rig
        prof = load_profile(
            resolve(profile, "profile"), rig_override=resolve(rig, "rig") if rig else None
        )
        self._n += 1
        log = Path(out) if out is not None else self.log_dir / f"{self._n:03d}-{prof.name}.mcap"
        log.parent.mkdir(parents=True, exist_ok=True)
        if self.kind == "emulator":
            result = run_in_process(prof, log, seed)
        else:
            from pmsm_hil.protocol.session import Session
            from pmsm_hil.runner import RunOptions, run_profile

            link = self._link(prof, seed)
            try:
                on_emulator = self.can is not None and self.can.startswith("emulator")
                result = run_profile(
                    prof,
                    Session(link),
                    log,
                    RunOptions(
                        seed=seed if on_emulator else None,
                        log_sync="wall" if on_emulator else "batch",
                    ),
                )
            finally:
                link.close()
        return HilRun(profile=prof, result=result, log_path=log)


# ----------------------------------------------------------------------------------- pytest hooks


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("pmsm-hil", "pmsm-hil hardware-in-the-loop tests")
    group.addoption(
        "--hil-port",
        default=None,
        metavar="PORT",
        help="run hil_device on the rig at this serial port (default: the emulator)",
    )
    group.addoption(
        "--hil-can",
        default=None,
        metavar="SPEC",
        help="run hil_device on the rig on this CAN interface (python-can spec, as pmsm-hil run "
        "--can; `emulator`: the emulator over CAN)",
    )
    group.addoption(
        "--hil-rig",
        default=None,
        metavar="RIG",
        help="rig file or shipped name replacing each profile's: the emulator's plant; on a real "
        "rig only the firmware's encoder counts (4 x its encoder lines) and the log's rig record",
    )
    group.addoption(
        "--hil-seed",
        type=int,
        default=1,
        metavar="N",
        help="emulator seed (default 1; a real rig has none)",
    )


_SEED = pytest.StashKey[int]()


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "hil_rig: needs a rig's path (--hil-port, or --hil-can: `--hil-can emulator` is the "
        "emulator on CAN through that path); skipped on the in-process emulator",
    )
    config.stash[_SEED] = _checked_options(config)
    if config.getoption("--hil-can"):
        from pmsm_hil.transport import quiet_python_can  # as the CLI does

        quiet_python_can()
    taken = _option_taken_for_a_test_path(config)
    if taken:
        config.issue_config_time_warning(pytest.PytestConfigWarning(taken), stacklevel=2)


def _option_taken_for_a_test_path(config: pytest.Config) -> str | None:
    """pytest finds its rootdir and ini file before it knows a plugin's options: in `pytest
    --hil-port /dev/ttyUSB0` it takes the port for a test path, roots at /dev and reads no ini
    file of the folder it runs in (its markers, addopts, testpaths). What to write instead, when
    that happened; `--hil-port=/dev/ttyUSB0` (one word) is not taken for a path."""
    here, root = config.invocation_params.dir, config.rootpath
    if here.is_relative_to(root):
        return None
    for option, value in itertools.pairwise(config.invocation_params.args):
        if (
            option in ("--hil-port", "--hil-rig")
            and os.path.exists(value)
            and Path(value).absolute().is_relative_to(root)
        ):
            return (
                f"pytest took {value} (the value of {option}) for a test path when it looked "
                f"for its configuration: rootdir {root}, and an ini file of {here} "
                "(pytest.ini, pyproject.toml ...) is not read. "
                f"Write {option}={value} (one word), or name the tests' folder too"
            )
    return None


def _checked_options(config: pytest.Config) -> int:
    """The --hil-* options checked once, before any test: pytest.UsageError naming the option and
    its value (pytest prints it as one line and exits with code 4); the seed as a number."""
    port, can, rig = (config.getoption(o) for o in ("--hil-port", "--hil-can", "--hil-rig"))
    if port and can:
        raise pytest.UsageError(
            f"--hil-port {port} and --hil-can {can}: give one of them (a rig on a serial port or "
            "on CAN), not both"
        )
    if port and not os.path.exists(port):
        raise pytest.UsageError(
            f"--hil-port {port}: no such serial port (is the adapter plugged in?)"
        )
    if can:
        from pmsm_hil.errors import TransportSpecError
        from pmsm_hil.transport.can_bus import parse_spec

        try:
            parse_spec(can, option="--hil-can")
        except TransportSpecError as e:
            raise pytest.UsageError(str(e)) from None
    if rig:
        from pmsm_hil.profiles import ProfileError, load_rig
        from pmsm_hil.profiles.shipped import resolve

        try:
            load_rig(resolve(rig, "rig"))
        except ProfileError as e:
            raise pytest.UsageError(f"--hil-rig {rig}: {e}") from None
    from pmsm_hil.seeds import SEED_MAX

    seed = config.getoption("--hil-seed")
    if not 0 <= seed <= SEED_MAX:
        raise pytest.UsageError(f"--hil-seed {seed}: give a whole number 0..{SEED_MAX}")
    return seed


def _has_rig(config) -> bool:
    return bool(config.getoption("--hil-port") or config.getoption("--hil-can"))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if _has_rig(config):
        return
    skip = pytest.mark.skip(reason="needs a real rig: give --hil-port PORT or --hil-can SPEC")
    for item in items:
        if "hil_rig" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def hil_device(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> HilDevice:
    """The device under test (session-wide): the emulator, or the rig given by --hil-port/--hil-can
    (the options checked in pytest_configure)."""
    cfg = request.config
    return HilDevice(
        port=cfg.getoption("--hil-port"),
        can=cfg.getoption("--hil-can"),
        rig=cfg.getoption("--hil-rig"),
        seed=cfg.stash[_SEED],
        log_dir=tmp_path_factory.mktemp("hil-logs"),
    )
