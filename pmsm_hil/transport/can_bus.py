"""CAN buses: `--can SPEC` for any python-can interface, the emulator on a socketcand endpoint, and an
in-process CAN bus to the emulated device (docs/can.md). These are buses, not links: the protocol's
CAN link (pmsm_hil.protocol.can_link) goes on top of them in pmsm_hil.device.

SPEC = INTERFACE:CHANNEL[,bitrate=N][,node=N][,key=value...]   (extra keys go to can.Bus as is)
    socketcand:emu0@127.0.0.1:29536      python-can's socketcand client (channel@host:port)
    socketcan:can0   pcan:PCAN_USBBUS1   kvaser:0   slcan:/dev/ttyACM0   ixxat:0   virtual:ch0
    emulator (or an empty SPEC)          start the emulator and talk to it over socketcand
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from pmsm_hil.emulator import process as emu_process
from pmsm_hil.errors import TransportError, TransportSpecError

if TYPE_CHECKING:
    import can

    from pmsm_hil.emulator.fwlib import EmulatedDevice

# a fault hook: the frames [(identifier, data)] on their way, to the frames to deliver
FrameFault = Callable[[list[tuple[int, bytes]]], list[tuple[int, bytes]]]

INTERFACES = (
    "socketcand",
    "socketcan",
    "pcan",
    "kvaser",
    "slcan",
    "ixxat",
    "virtual",
    "vector",
    "serial",
    "usb2can",
    "nican",
    "iscan",
    "neovi",
    "gs_usb",
    "cantact",
    "udp_multicast",
    "seeedstudio",
    "canalystii",
    "systec",
    "etas",
    "nixnet",
    "robotell",
    "pcan_basic",
)
SPEC_HELP = (
    "INTERFACE:CHANNEL[,bitrate=N][,node=N], e.g. socketcand:emu0@127.0.0.1:29536, "
    "socketcan:can0, pcan:PCAN_USBBUS1, kvaser:0, slcan:/dev/ttyACM0, ixxat:0, virtual:ch0; "
    "or `emulator`"
)


@dataclass
class CanSpec:
    interface: str
    channel: str
    bitrate: int | None = None  # None: not given (the device factory fills in the profile's)
    node: int | None = None
    host: str | None = None  # socketcand only
    port: int | None = None
    extra: dict = field(default_factory=dict)

    @property
    def is_emulator(self) -> bool:
        return self.interface == "emulator"

    def text(self) -> str:
        where = (
            f"{self.channel}@{self.host}:{self.port}"
            if self.interface == "socketcand"
            else self.channel
        )
        opts = ""
        if self.bitrate is not None:
            opts += f",bitrate={self.bitrate}"
        if self.node is not None:
            opts += f",node={self.node}"
        return f"{self.interface}:{where}{opts}"


def _number(key: str, value: str, where: str) -> int:
    try:
        return int(float(value)) if key == "bitrate" else int(value, 0)
    except ValueError:
        raise TransportSpecError(f"{where}: {key}={value} is not a number") from None


def parse_spec(spec: str | None, option: str = "--can") -> CanSpec:
    """A SPEC string -> CanSpec; TransportSpecError that names the problem, the format and the
    option the SPEC was given to (``option``: `--can` of the CLI, `--hil-can` of the pytest
    plugin)."""
    text = (spec or "").strip()
    where = f"{option} {text}"
    parts = [p.strip() for p in text.split(",")] if text else ["emulator"]
    head, opts = parts[0] or "emulator", parts[1:]
    if head == "emulator":
        iface, channel = "emulator", ""
    elif ":" not in head:
        raise TransportSpecError(f"{where}: expected {SPEC_HELP}")
    else:
        iface, channel = head.split(":", 1)
    iface = iface.strip().lower()
    if iface != "emulator" and iface not in INTERFACES:
        raise TransportSpecError(
            f"{where}: unknown interface {iface!r} (python-can interfaces: "
            f"{', '.join(INTERFACES[:8])}, ...)"
        )
    out = CanSpec(iface, channel)
    for opt in opts:
        if "=" not in opt:
            raise TransportSpecError(f"{where}: option {opt!r} is not key=value")
        k, v = (s.strip() for s in opt.split("=", 1))
        if k == "bitrate":
            out.bitrate = _number(k, v, where)
            if not 10_000 <= out.bitrate <= 1_000_000:
                raise TransportSpecError(
                    f"{where}: bitrate {out.bitrate} is outside classic CAN's 10 kbit/s .. 1 Mbit/s"
                )
        elif k == "node":
            out.node = _number(k, v, where)
            if not 0 <= out.node <= 15:
                raise TransportSpecError(f"{where}: node {out.node} must be 0..15")
        else:
            out.extra[k] = v
    if iface == "socketcand":
        try:
            ch, hostport = channel.rsplit("@", 1)
            host, port = hostport.rsplit(":", 1)
            out.channel, out.host, out.port = ch, host, int(port)
        except ValueError:
            raise TransportSpecError(
                f"{where}: socketcand needs CHANNEL@HOST:PORT, e.g. socketcand:emu0@127.0.0.1:29536"
            ) from None
    elif iface != "emulator" and not channel:
        raise TransportSpecError(f"{where}: no channel given ({SPEC_HELP})")
    return out


def open_bus(spec: CanSpec) -> can.BusABC:
    """A python-can bus for spec, with clear errors for a missing interface or device."""
    try:
        import can
    except ImportError as e:  # pragma: no cover - python-can is a dependency
        raise TransportError("python-can is not installed (pip install python-can)") from e
    kw = dict(spec.extra)
    if spec.interface == "socketcand":
        kw.update(host=spec.host, port=spec.port)
        import socket

        try:  # python-can retries a refused connection for 10 s: fail fast instead
            socket.create_connection((spec.host, spec.port), timeout=2.0).close()
        except OSError as e:
            raise TransportError(
                f"CAN socketcand {spec.host}:{spec.port}: cannot connect ({e}); is "
                f"`pmsm-hil emulate --can` (or socketcand) running?"
            ) from e
    elif spec.interface not in ("virtual",) and spec.bitrate is not None:
        kw.setdefault("bitrate", spec.bitrate)
    try:
        return can.Bus(interface=spec.interface, channel=spec.channel, **kw)
    except ImportError as e:
        raise TransportError(
            f"CAN interface {spec.interface}: a driver or package is missing ({e})"
        ) from e
    except (can.CanError, OSError, ValueError, TypeError, NotImplementedError) as e:
        raise TransportError(f"CAN {spec.text()}: cannot open the interface: {e}") from e
    except Exception as e:  # python-can backends raise their own types
        raise TransportError(
            f"CAN {spec.text()}: cannot open the interface: {type(e).__name__}: {e}"
        ) from e


class CanEmulator:
    """Starts the emulator on CAN (`python -P -m pmsm_hil.emulator --can`) as a process; `spec` is
    its socketcand endpoint."""

    def __init__(
        self,
        motor_path: str | None,
        rig_path: str | None,
        seed: int,
        bitrate: int,
        node: int,
        start_timeout_s: float = 20.0,
        extra_args: list[str] | None = None,
        pace: float | None = None,
    ):
        args = ["--can", "--seed", str(seed), "--can-bitrate", str(bitrate), "--node", str(node)]
        if pace:
            args += ["--pace", repr(float(pace))]
        if motor_path:
            args += ["--motor", str(motor_path)]
        if rig_path:
            args += ["--rig", str(rig_path)]
        self.proc = emu_process.start(args + (extra_args or []))
        self.spec_text = emu_process.wait_for_announcement(self.proc, "can: ", start_timeout_s)
        self.spec = parse_spec(self.spec_text)
        self.spec.bitrate, self.spec.node = bitrate, node

    def close(self) -> None:
        emu_process.stop(self.proc)


class InProcessCanBus:
    """A python-can-like bus whose other end is the emulated device in this process (no socket).

    The device runs only when the host reads, a chunk of control periods at a time, as with
    pmsm_hil.transport.inproc. `fault` (optional) is called with each frame list on its way to the
    host or the device and returns the frames to deliver (tests corrupt or drop frames with it)."""

    channel_info = "in-process emulator"

    def __init__(
        self,
        device: EmulatedDevice,
        chunk_ticks: int = 400,
        fault_d2h: FrameFault | None = None,
        fault_h2d: FrameFault | None = None,
    ):
        self.dev = device
        self.chunk_ticks = chunk_ticks
        self.fault_d2h = fault_d2h
        self.fault_h2d = fault_h2d
        self._rx: list = []
        self.recorded: list[tuple[float, int, bytes]] | None = (
            None  # set to [] to record (t, id, data)
        )
        self._ts = device.get("ts_s")

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        frames = [(msg.arbitration_id, bytes(msg.data))]
        if self.fault_h2d is not None:
            frames = self.fault_h2d(frames)
        for ident, data in frames:
            self.dev.can_rx(ident, data)

    def recv_batch(self) -> list[tuple[int, bytes]]:
        """One chunk of device time: the frames sent meanwhile, [(identifier, data)]."""
        out = self._rx[::-1]
        self._rx = []
        return out + self._run_chunk()

    def _run_chunk(self) -> list[tuple[int, bytes]]:
        """Run the device for one chunk; the frames it sent (recorded, then through the fault hook)."""
        self.dev.run(self.chunk_ticks if self.dev.active else 0)
        frames = self.dev.can_take()
        if self.recorded is not None:
            self.recorded.extend((isr * self._ts, i, d) for i, d, isr in frames)
        pairs = [(i, d) for i, d, _ in frames]
        if self.fault_d2h is not None:
            pairs = self.fault_d2h(pairs)
        return pairs

    def recv(self, timeout: float | None = None) -> can.Message | None:
        import can

        if not self._rx:
            self._rx = self._run_chunk()[::-1]
            if not self._rx:
                return None
        ident, data = self._rx.pop()
        return can.Message(arbitration_id=ident, data=data, is_extended_id=False, is_rx=True)

    def shutdown(self) -> None:
        pass
