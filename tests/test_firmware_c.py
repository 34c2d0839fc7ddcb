"""The firmware's C unit tests, built with the C28x-strict warnings as errors (firmware/Makefile)."""
from __future__ import annotations

import shutil
import subprocess

import pytest


def test_firmware_core_builds_strict_and_its_c_tests_pass(root, tmp_path):
    if shutil.which("make") is None:
        pytest.fail("make is needed to build the firmware's C tests")
    build = tmp_path / "fwbuild"
    r = subprocess.run(["make", "-C", str(root / "firmware"), "test", f"BUILD={build}"],
                       capture_output=True, text=True, timeout=600)
    print(r.stdout[-5000:])
    assert r.returncode == 0, r.stdout[-5000:] + r.stderr[-5000:]
    assert " 0 failed" in r.stdout
    assert "FAIL" not in r.stdout


def test_f28335_board_sources_compile_against_the_register_stub(root):
    """The board support cannot be built with TI's cl2000 here; it is compile-checked on the PC
    against a stub of the device headers, and its register-free arithmetic is tested."""
    r = subprocess.run(["make", "-C", str(root / "firmware" / "board" / "f28335"), "hostcheck"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "all checks passed" in r.stdout
