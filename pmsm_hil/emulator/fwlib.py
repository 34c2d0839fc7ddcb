"""ctypes binding of the emulator's C API (firmware/sim/emu.h) inside the pmsm_hil._fw extension."""
from __future__ import annotations

import ctypes
from functools import lru_cache


@lru_cache(maxsize=1)
def lib() -> ctypes.CDLL:
    """The extension's shared library, with argument types declared."""
    from pmsm_hil import _fw

    so = ctypes.CDLL(_fw.__file__)
    so.emu_size.restype = ctypes.c_size_t
    so.emu_init.argtypes = [ctypes.c_void_p]
    so.emu_set.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_double]
    so.emu_set.restype = ctypes.c_int
    so.emu_get.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_double)]
    so.emu_get.restype = ctypes.c_int
    so.emu_reset.argtypes = [ctypes.c_void_p]
    so.emu_rx.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_uint32]
    so.emu_run.argtypes = [ctypes.c_void_p, ctypes.c_uint32, ctypes.c_void_p, ctypes.c_uint32,
                           ctypes.POINTER(ctypes.c_uint32)]
    so.emu_run.restype = ctypes.c_uint32
    for name in ("emu_isr_count", "emu_heartbeat_isr"):
        getattr(so, name).argtypes = [ctypes.c_void_p]
        getattr(so, name).restype = ctypes.c_uint32
    for name in ("emu_state", "emu_active"):
        getattr(so, name).argtypes = [ctypes.c_void_p]
        getattr(so, name).restype = ctypes.c_int
    return so


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
        for key, value in settings.items():
            if self._lib.emu_set(self._p, key.encode(), float(value)) != 0:
                raise KeyError(f"emulator has no setting {key!r}")
        self._lib.emu_reset(self._p)

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
        ticks = self._lib.emu_run(self._p, max(0, int(max_ticks)), self._out, self._out_cap,
                                  ctypes.byref(self._n))
        return ticks, self._out.raw[: self._n.value]

    @property
    def isr_count(self) -> int:
        return self._lib.emu_isr_count(self._p)

    @property
    def heartbeat_isr(self) -> int:
        return self._lib.emu_heartbeat_isr(self._p)

    @property
    def active(self) -> bool:
        return bool(self._lib.emu_active(self._p))

    @property
    def state(self) -> int:
        return self._lib.emu_state(self._p)
