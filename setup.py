"""Builds the C extension pmsm_hil._fw: the firmware core plus the emulator's sim board.

The extension exports a plain C API (firmware/sim/emu.h) that pmsm_hil.emulator.fwlib loads with
ctypes; its Python module init is only there so that pip builds and installs it like any extension.
"""
import hashlib
from glob import glob

from setuptools import Extension, find_packages, setup

sources = sorted(glob("firmware/core/*.c")) + sorted(glob("firmware/sim/*.c")) + ["pmsm_hil/_fw_module.c"]


def source_sha256():
    """The build's identity (emu_source_id, docs/sweep.md): SHA-256 over the names and contents
    of the C sources and headers compiled in. A sweep's and a benchmark's journal keys carry it, so
    that results of another firmware are never taken for this one's."""
    h = hashlib.sha256()
    for path in sorted(set(sources + glob("firmware/core/*.h") + glob("firmware/sim/*.h"))):
        with open(path, "rb") as f:
            h.update(path.encode() + b"\0" + f.read() + b"\0")
    return h.hexdigest()[:16]


# The shipped profiles, motor, rig and flux-map files (profiles/) are package data of
# pmsm_hil.shipped, so that an installed pmsm-hil finds them from any directory (docs/profiles.md);
# the shipped sweep files (sweeps/) likewise, as pmsm_hil.shipped.sweeps (docs/sweep.md).
SHIPPED = ["*.yaml", "motors/*.yaml", "rigs/*.yaml", "maps/*.csv"]
# The CAN database (firmware/proto/pmsm_proto.dbc, generated) as pmsm_hil.proto, so that an
# installed pmsm-hil has it for a CAN analyser; `pmsm-hil profiles` prints its path (docs/can.md).

setup(
    packages=find_packages(include=["pmsm_hil", "pmsm_hil.*"])
    + ["pmsm_hil.shipped", "pmsm_hil.shipped.sweeps", "pmsm_hil.proto"],
    package_dir={
        "pmsm_hil.shipped": "profiles",
        "pmsm_hil.shipped.sweeps": "sweeps",
        "pmsm_hil.proto": "firmware/proto",
    },
    package_data={
        "pmsm_hil.shipped": SHIPPED,
        "pmsm_hil.shipped.sweeps": ["*.yaml"],
        "pmsm_hil.proto": ["pmsm_proto.dbc"],
        "pmsm_hil.live": ["foxglove-layout.json"],  # run --foxglove prints its installed path
        # PEP 561: a user's type checker reads the package's annotations (scripts, notebooks)
        "pmsm_hil": ["py.typed"],
    },
    ext_modules=[
        Extension(
            "pmsm_hil._fw",
            sources=sources,
            include_dirs=["firmware/core", "firmware/sim"],
            define_macros=[("EMU_SOURCE_SHA256", '"%s"' % source_sha256())],
            # -fno-semantic-interposition: calls between the extension's own functions are direct
            # (and may be inlined) instead of going through the PLT; no effect on the arithmetic
            # -flto: the emulator loop crosses some 40 small functions per period in a dozen
            # files (fw_active, cc_step, the plant's steps...); link-time optimisation inlines
            # them across files. Same floating-point operations in the same order (no
            # contraction in ISO C mode, no FMA on the baseline x86-64): the device data are
            # bit for bit those of the build without it
            extra_compile_args=["-std=c99", "-O3", "-fno-math-errno", "-fno-trapping-math",
                                "-fno-semantic-interposition", "-flto=auto", "-Wall", "-Wextra"],
            extra_link_args=["-O3", "-flto=auto"],
            libraries=["m"],
        )
    ]
)
