import os
import signal
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture
def root() -> Path:
    return ROOT


@pytest.fixture
def data() -> Path:
    return DATA


@pytest.fixture(scope="session")
def built_package(tmp_path_factory) -> Path:
    """The package as setup.py installs it (build_py: the Python files and the package data) in
    a folder of its own, built once for the tests that check what an install holds (one of them
    copies the compiled extension beside it, to import the package from there)."""
    import subprocess
    import sys

    lib = tmp_path_factory.mktemp("build") / "lib"
    r = subprocess.run(
        [sys.executable, "setup.py", "-q", "build_py", "--build-lib", str(lib)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    return lib


@pytest.fixture()
def ws(tmp_path, monkeypatch):
    """A work directory laid out like profiles/ (motors/, rigs/) with paper A's motor and the
    default rig, as the working directory, so that messages carry short relative paths."""
    import shutil

    (tmp_path / "motors").mkdir()
    (tmp_path / "rigs").mkdir()
    shutil.copy(ROOT / "profiles" / "motors" / "paper-a-ipmsm.yaml", tmp_path / "motors")
    shutil.copy(ROOT / "profiles" / "rigs" / "default.yaml", tmp_path / "rigs")
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture(autouse=True)
def _chdir_tmp(tmp_path, monkeypatch):
    """Tests run in a temporary folder so that default log paths do not litter the tree."""
    monkeypatch.chdir(tmp_path)
    os.environ.setdefault("COLUMNS", "160")
    yield


def _held_signals() -> set:
    return (
        set(signal.pthread_sigmask(signal.SIG_BLOCK, set()))
        if hasattr(signal, "pthread_sigmask")
        else set()
    )


@pytest.fixture(autouse=True)
def _no_signal_left_blocked():
    """No test may leave a signal blocked in this process: the child processes later tests start
    inherit the mask (a child once never saw its SIGINT and looped until its timeout)."""
    before = _held_signals()
    yield
    leaked = _held_signals() - before
    if leaked:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, leaked)  # the next tests start clean
        pytest.fail(f"signals left blocked by this test: {sorted(s.name for s in leaked)}")
