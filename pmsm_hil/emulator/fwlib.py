"""ctypes binding of the emulator's C API (firmware/sim/emu.h) inside the pmsm_hil._fw extension."""

from __future__ import annotations

import ctypes
from functools import lru_cache


@lru_cache(maxsize=1)
def lib() -> ctypes.CDLL:
    """The extension's shared library, with argument types declared. PMSM_HIL_FW_LIB names another
    build of the same sources instead (the sanitizer build of `make -C firmware sanitize`)."""
    import importlib
    import os

    path = os.environ.get("PMSM_HIL_FW_LIB") or importlib.import_module("pmsm_hil._fw").__file__
    so = ctypes.CDLL(path)
    so.emu_size.restype = ctypes.c_size_t
    so.emu_init.argtypes = [ctypes.c_void_p]
    so.emu_set.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_double]
    so.emu_set.restype = ctypes.c_int
    so.emu_get.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_double)]
    so.emu_get.restype = ctypes.c_int
    so.emu_reset.argtypes = [ctypes.c_void_p]
    so.emu_set_array.argtypes = [
        ctypes.c_void_p,
        ctypes.c_char_p,
        ctypes.POINTER(ctypes.c_double),
        ctypes.c_uint32,
    ]
    so.emu_set_array.restype = ctypes.c_int
    so.emu_check.argtypes = [ctypes.c_void_p]
    so.emu_check.restype = ctypes.c_char_p
    so.emu_source_id.restype = ctypes.c_char_p
    so.emu_plant_flux.argtypes = [
        ctypes.c_void_p,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.POINTER(ctypes.c_double),
    ]
    so.emu_plant_truth.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double), ctypes.c_int]
    so.emu_plant_truth.restype = ctypes.c_int
    so.emu_rx.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_uint32]
    so.emu_run.argtypes = [
        ctypes.c_void_p,
        ctypes.c_uint32,
        ctypes.c_void_p,
        ctypes.c_uint32,
        ctypes.POINTER(ctypes.c_uint32),
    ]
    so.emu_run.restype = ctypes.c_uint32
    so.emu_state_change.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint32)]
    so.emu_state_change.restype = ctypes.c_uint32
    for name in ("emu_isr_count", "emu_heartbeat_isr"):
        getattr(so, name).argtypes = [ctypes.c_void_p]
        getattr(so, name).restype = ctypes.c_uint32
    so.emu_can_rx.argtypes = [ctypes.c_void_p, ctypes.c_uint32, ctypes.c_char_p, ctypes.c_uint32]
    so.emu_can_take.argtypes = [ctypes.c_void_p] + [ctypes.c_void_p] * 4 + [ctypes.c_uint32]
    so.emu_can_take.restype = ctypes.c_uint32
    for name in ("emu_state", "emu_active"):
        getattr(so, name).argtypes = [ctypes.c_void_p]
        getattr(so, name).restype = ctypes.c_int
    for name in ("emu_setting_name", "emu_truth_name"):
        getattr(so, name).argtypes = [ctypes.c_uint32]
        getattr(so, name).restype = ctypes.c_char_p
    return so


def _names(fn) -> tuple[str, ...]:
    out, i = [], 0
    while (name := fn(i)) is not None:
        out.append(name.decode())
        i += 1
    return tuple(out)


@lru_cache(maxsize=1)
def setting_keys() -> tuple[str, ...]:
    """The sim board's setting keys (firmware/sim/emu_table.h EMU_SETTINGS)."""
    return _names(lib().emu_setting_name)


@lru_cache(maxsize=1)
def truth_keys() -> tuple[str, ...]:
    """The order of emu_plant_truth's values (firmware/sim/emu_table.h EMU_TRUTH)."""
    return _names(lib().emu_truth_name)


def __getattr__(name: str) -> tuple[str, ...]:
    # SETTING_KEYS and TRUTH_KEYS come from the C table, read when first asked for
    if name == "SETTING_KEYS":
        return setting_keys()
    if name == "TRUTH_KEYS":
        return truth_keys()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class EmulatedDevice:
    """The firmware core on the sim board, stepped in device time."""

    def __init__(self, settings: dict[str, float] | None = None, out_cap: int = 1 << 16):
        self._lib = lib()
        self._mem = ctypes.create_string_buffer(self._lib.emu_size())
        self._p = ctypes.cast(self._mem, ctypes.c_void_p)
        self._lib.emu_init(self._p)
        self._out = ctypes.create_string_buffer(out_cap)
        self._out_cap = out_cap
        self._n = ctypes.c_uint32(0)
        if settings:
            self.configure(settings)

    def configure(self, settings: dict[str, float]) -> None:
        """Apply settings (numbers, or sequences of numbers for the array keys such as the flux
        map) and reset; raises KeyError for an unknown key, ValueError for unusable values."""
        for key, value in settings.items():
            if isinstance(value, (list, tuple)):
                arr = (ctypes.c_double * len(value))(*[float(v) for v in value])
                if self._lib.emu_set_array(self._p, key.encode(), arr, len(value)) != 0:
                    raise KeyError(f"emulator has no array setting {key!r} (or too many values)")
            elif self._lib.emu_set(self._p, key.encode(), float(value)) != 0:
                raise KeyError(f"emulator has no setting {key!r}")
        self._lib.emu_reset(self._p)
        err = self._lib.emu_check(self._p)
        if err:
            raise ValueError(f"emulator settings: {err.decode()}")

    def plant_truth(self) -> dict[str, float]:
        """The plant's state now (every field of plant_truth_t, plus the firmware tick)."""
        keys = truth_keys()
        out = (ctypes.c_double * len(keys))()
        self._lib.emu_plant_truth(self._p, out, len(keys))
        return dict(zip(keys, list(out), strict=False))

    def plant_flux(self, i_d_a: float, i_q_a: float, theta_e_rad: float = 0.0) -> dict[str, float]:
        """The plant's magnetics at one point (flux linkages, incremental inductances, torque)."""
        out = (ctypes.c_double * 8)()
        self._lib.emu_plant_flux(self._p, i_d_a, i_q_a, theta_e_rad, out)
        keys = (
            "psi_d_wb",
            "psi_q_wb",
            "l_dd_h",
            "l_dq_h",
            "l_qd_h",
            "l_qq_h",
            "t_extra_nm",
            "torque_nm",
        )
        return dict(zip(keys, list(out), strict=False))

    def get(self, key: str) -> float:
        v = ctypes.c_double()
        if self._lib.emu_get(self._p, key.encode(), ctypes.byref(v)) != 0:
            raise KeyError(f"emulator has no reading {key!r}")
        return v.value

    def rx(self, data: bytes) -> None:
        if data:
            self._lib.emu_rx(self._p, data, len(data))

    def run(self, max_ticks: int) -> tuple[int, bytes]:
        """Run up to max_ticks control periods; returns (periods run, octets sent on the UART)."""
        ticks = self._lib.emu_run(
            self._p, max(0, int(max_ticks)), self._out, self._out_cap, ctypes.byref(self._n)
        )
        return ticks, ctypes.string_at(self._out, self._n.value)  # only the octets written

    def can_rx(self, ident: int, data: bytes) -> None:
        """A CAN frame from the host (docs/can.md)."""
        self._lib.emu_can_rx(self._p, ident, bytes(data), len(data))

    def can_take(self, cap: int = 4096) -> list[tuple[int, bytes, int]]:
        """The CAN frames the sim board sent since the last call: [(identifier, data, isr_count)]."""
        if not hasattr(self, "_can_bufs"):
            self._can_bufs = (
                (ctypes.c_uint32 * cap)(),
                (ctypes.c_uint8 * cap)(),
                ctypes.create_string_buffer(8 * cap),
                (ctypes.c_uint32 * cap)(),
                cap,
            )
        ids, dlc, data, isr, cap = self._can_bufs
        n = self._lib.emu_can_take(self._p, ids, dlc, data, isr, cap)
        if n == 0:
            return []
        raw = data.raw
        return [(ids[i], raw[8 * i : 8 * i + dlc[i]], isr[i]) for i in range(n)]

    @property
    def isr_count(self) -> int:
        return self._lib.emu_isr_count(self._p)

    @property
    def heartbeat_isr(self) -> int:
        return self._lib.emu_heartbeat_isr(self._p)

    def state_change(self) -> tuple[int, int]:
        """(isr count of the last state change, isr count of the last heartbeat then)."""
        hb = ctypes.c_uint32(0)
        isr = self._lib.emu_state_change(self._p, ctypes.byref(hb))
        return int(isr), int(hb.value)

    @property
    def active(self) -> bool:
        return bool(self._lib.emu_active(self._p))

    @property
    def state(self) -> int:
        return self._lib.emu_state(self._p)


def source_id() -> str:
    """The firmware build's identity: a hash of the C sources it was compiled from ("unknown" for
    a build without it). Sweeps and benchmarks key their journals with it (docs/sweep.md)."""
    return str(lib().emu_source_id().decode())


def other_build(firmware: str) -> str | None:
    """Why this process cannot run work planned for the firmware build ``firmware`` (a worker
    of a cluster with another pmsm-hil installed), or None when it is this build."""
    own = source_id()
    if own == firmware:
        return None
    return (
        f"this worker's firmware build is {own}, the client's {firmware}: install the same "
        "pmsm-hil on every worker"
    )
