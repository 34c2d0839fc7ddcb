"""The firmware's C unit tests, built with the C28x-strict warnings as errors (firmware/Makefile)."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest


def test_firmware_core_builds_strict_and_its_c_tests_pass(root, tmp_path):
    if shutil.which("make") is None:
        pytest.fail("make is needed to build the firmware's C tests")
    build = tmp_path / "fwbuild"
    r = subprocess.run(
        ["make", "-j2", "-C", str(root / "firmware"), "test", f"BUILD={build}"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    print(r.stdout[-5000:])
    assert r.returncode == 0, r.stdout[-5000:] + r.stderr[-5000:]
    assert " 0 failed" in r.stdout
    assert "FAIL" not in r.stdout
    # every C test program ran and said so (two at a time, each one's lines together)
    programs = set(re.findall(r"^== \S+/tests/(test_\w+)$", r.stdout, re.M))
    sources = {p.stem for p in (root / "firmware" / "tests").glob("test_*.c")}
    assert programs == sources, sources ^ programs


def test_f28335_board_sources_compile_against_the_register_stub(root):
    """The board support cannot be built with TI's cl2000 here; it is compile-checked on the PC
    against a stub of the device headers, and its register-free arithmetic is tested."""
    r = subprocess.run(
        ["make", "-C", str(root / "firmware" / "board" / "f28335"), "hostcheck"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "all checks passed" in r.stdout


C_STANDARD_HEADERS = {
    "assert.h",
    "complex.h",
    "ctype.h",
    "errno.h",
    "fenv.h",
    "float.h",
    "inttypes.h",
    "iso646.h",
    "limits.h",
    "locale.h",
    "math.h",
    "setjmp.h",
    "signal.h",
    "stdarg.h",
    "stdbool.h",
    "stddef.h",
    "stdint.h",
    "stdio.h",
    "stdlib.h",
    "string.h",
    "tgmath.h",
    "time.h",
    "wchar.h",
    "wctype.h",
}
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]', re.M)


def core_includes(core):
    """(file, header, quoted) for every #include of the firmware core's files."""
    out = []
    for path in sorted(list(core.glob("*.c")) + list(core.glob("*.h"))):
        for m in INCLUDE.finditer(path.read_text()):
            out.append((path.name, m.group(2), m.group(1) == '"'))
    return out


def stray_includes(core):
    """Includes of anything but a header of core itself ("x.h") or a C standard header (<x.h>)."""
    return [
        (f, h)
        for f, h, quoted in core_includes(core)
        if (quoted and ("/" in h or not (core / h).is_file()))
        or (not quoted and h not in C_STANDARD_HEADERS)
    ]


def test_firmware_core_includes_only_core_and_the_c_standard_headers(root):
    core = root / "firmware" / "core"
    assert len(core_includes(core)) > 50  # the scan sees the core's includes
    bad = stray_includes(core)
    assert not bad, "firmware/core includes outside core and the C standard headers: " + repr(bad)


def test_the_include_check_catches_a_stray_include(tmp_path):
    core = tmp_path / "core"
    core.mkdir()
    (core / "a.h").write_text("#include <stdint.h>\n")
    (core / "a.c").write_text(
        '#include "a.h"\n#include "../sim/plant.h"\n#include "b.h"\n#include <windows.h>\n'
    )
    assert stray_includes(core) == [("a.c", "../sim/plant.h"), ("a.c", "b.h"), ("a.c", "windows.h")]


def test_fuzz_targets_run_clean_for_half_a_minute(root, tmp_path):
    """firmware/fuzz/ (libFuzzer + ASan + UBSan): the frame parser, the CAN reassembly and the
    whole firmware on the sim board, from the committed seed corpus; no crash,
    no sanitizer report, no invariant broken; some of the whole-firmware inputs run the motor when
    the host falls silent (its seeds are real sessions). 10 s per target, two at a time: CI's short
    run is half a minute of fuzzing (measured: 250 000-330 000 inputs of the CAN reassembly,
    260 000-290 000 of the frame parser, 3 000-3 600 of the whole firmware, 59-81 of which ran
    the motor when the host fell silent).
    libFuzzer comes with clang only: without clang this is skipped (the long run: `make -C
    firmware fuzz FUZZ_SECONDS=...`, docs/faults.md)."""
    if shutil.which("clang") is None:
        pytest.skip("clang (libFuzzer) is not installed")
    r = subprocess.run(
        [
            "make",
            "-j2",
            "-C",
            str(root / "firmware"),
            "fuzz",
            "FUZZ_SECONDS=10",
            f"BUILD={tmp_path}",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout[-5000:] + r.stderr[-3000:]
    runs = [int(n) for n in re.findall(r"stat::number_of_executed_units: (\d+)", r.stdout)]
    assert len(runs) == 3 and min(runs) > 100, r.stdout
    assert "fuzz_can: accepted" in r.stdout and "not-sent accepted" in r.stdout
    silent = re.search(r"fuzz_fw: inputs \d+, running when the host fell silent (\d+)", r.stdout)
    assert silent and int(silent.group(1)) > 0, r.stdout
