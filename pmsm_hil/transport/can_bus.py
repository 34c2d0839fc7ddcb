"""CAN transports: `--can SPEC` for any python-can interface, the emulator on a socketcand endpoint,
and an in-process CAN loopback to the emulated device (docs/can.md).

SPEC = INTERFACE:CHANNEL[,bitrate=N][,node=N][,key=value...]   (extra keys go to can.Bus as is)
    socketcand:emu0@127.0.0.1:29536      python-can's socketcand client (channel@host:port)
    socketcan:can0   pcan:PCAN_USBBUS1   kvaser:0   slcan:/dev/ttyACM0   ixxat:0   virtual:ch0
    emulator (or an empty SPEC)          start the emulator and talk to it over socketcand
"""
from __future__ import annotations

from dataclasses import dataclass, field

from pmsm_hil.protocol import can_generated as cg
from pmsm_hil.protocol.can_link import CanLink
from pmsm_hil.emulator import process as emu_process
from pmsm_hil.transport.base import TransportError, TransportSpecError

INTERFACES = ("socketcand", "socketcan", "pcan", "kvaser", "slcan", "ixxat", "virtual", "vector",
              "serial", "usb2can", "nican", "iscan", "neovi", "gs_usb", "cantact", "udp_multicast",
              "seeedstudio", "canalystii", "systec", "etas", "nixnet", "robotell", "pcan_basic")
SPEC_HELP = ("INTERFACE:CHANNEL[,bitrate=N][,node=N], e.g. socketcand:emu0@127.0.0.1:29536, "
             "socketcan:can0, pcan:PCAN_USBBUS1, kvaser:0, slcan:/dev/ttyACM0, ixxat:0, virtual:ch0; "
             "or `emulator`")


@dataclass
class CanSpec:
    interface: str
    channel: str
    bitrate: int = cg.BITRATE
    node: int = cg.NODE
    host: str | None = None      # socketcand only
    port: int | None = None
    extra: dict = field(default_factory=dict)

    @property
    def is_emulator(self) -> bool:
        return self.interface == "emulator"

    def text(self) -> str:
        where = f"{self.channel}@{self.host}:{self.port}" if self.interface == "socketcand" else self.channel
        opts = ""
        if self.bitrate != cg.BITRATE:
            opts += f",bitrate={self.bitrate}"
        if self.node != cg.NODE:
            opts += f",node={self.node}"
        return f"{self.interface}:{where}{opts}"


def _number(key: str, value: str, spec: str) -> int:
    try:
        return int(float(value)) if key == "bitrate" else int(value, 0)
    except ValueError:
        raise TransportSpecError(f"--can {spec}: {key}={value} is not a number") from None


def parse_spec(spec: str | None) -> CanSpec:
    """A SPEC string -> CanSpec; TransportError that names the problem and the format."""
    text = (spec or "").strip()
    parts = [p.strip() for p in text.split(",")] if text else ["emulator"]
    head, opts = parts[0] or "emulator", parts[1:]
    if head == "emulator":
        iface, channel = "emulator", ""
    elif ":" not in head:
        raise TransportSpecError(f"--can {text}: expected {SPEC_HELP}")
    else:
        iface, channel = head.split(":", 1)
    iface = iface.strip().lower()
    if iface != "emulator" and iface not in INTERFACES:
        raise TransportSpecError(f"--can {text}: unknown interface {iface!r} (python-can interfaces: "
                             f"{', '.join(INTERFACES[:8])}, ...)")
    out = CanSpec(iface, channel)
    for opt in opts:
        if "=" not in opt:
            raise TransportSpecError(f"--can {text}: option {opt!r} is not key=value")
        k, v = (s.strip() for s in opt.split("=", 1))
        if k == "bitrate":
            out.bitrate = _number(k, v, text)
            if not 10_000 <= out.bitrate <= 1_000_000:
                raise TransportSpecError(f"--can {text}: bitrate {out.bitrate} is outside classic CAN's "
                                     f"10 kbit/s .. 1 Mbit/s")
        elif k == "node":
            out.node = _number(k, v, text)
            if not 0 <= out.node <= 15:
                raise TransportSpecError(f"--can {text}: node {out.node} must be 0..15")
        else:
            out.extra[k] = v
    if iface == "socketcand":
        try:
            ch, hostport = channel.rsplit("@", 1)
            host, port = hostport.rsplit(":", 1)
            out.channel, out.host, out.port = ch, host, int(port)
        except ValueError:
            raise TransportSpecError(f"--can {text}: socketcand needs CHANNEL@HOST:PORT, "
                                 f"e.g. socketcand:emu0@127.0.0.1:29536") from None
    elif iface != "emulator" and not channel:
        raise TransportSpecError(f"--can {text}: no channel given ({SPEC_HELP})")
    return out


def open_bus(spec: CanSpec):
    """A python-can bus for spec, with clear errors for a missing interface or device."""
    try:
        import can
    except ImportError as e:  # pragma: no cover - python-can is a dependency
        raise TransportError("python-can is not installed (pip install python-can)") from e
    kw = dict(spec.extra)
    if spec.interface == "socketcand":
        kw.update(host=spec.host, port=spec.port)
        import socket
        try:   # python-can retries a refused connection for 10 s: fail fast instead
            socket.create_connection((spec.host, spec.port), timeout=2.0).close()
        except OSError as e:
            raise TransportError(f"CAN socketcand {spec.host}:{spec.port}: cannot connect ({e}); is "
                                 f"`pmsm-hil emulate --can` (or socketcand) running?") from e
    elif spec.interface not in ("virtual",):
        kw.setdefault("bitrate", spec.bitrate)
    try:
        return can.Bus(interface=spec.interface, channel=spec.channel, **kw)
    except ImportError as e:
        raise TransportError(f"CAN interface {spec.interface}: a driver or package is missing ({e})") from e
    except (can.CanError, OSError, ValueError, TypeError, NotImplementedError) as e:
        raise TransportError(f"CAN {spec.text()}: cannot open the interface: {e}") from e
    except Exception as e:   # python-can backends raise their own types
        raise TransportError(f"CAN {spec.text()}: cannot open the interface: {type(e).__name__}: {e}") from e


def open_can(spec: CanSpec, on_close=None, name: str | None = None) -> CanLink:
    bus = open_bus(spec)
    return CanLink(bus, node=spec.node, bit_rate=spec.bitrate,
                   name=name or f"CAN {spec.text()} node {spec.node}", on_close=on_close)


class CanEmulator:
    """Starts `pmsm-hil emulate --can` as a process; `link` talks to it over socketcand."""

    def __init__(self, motor_path: str | None, rig_path: str | None, seed: int, bitrate: int = cg.BITRATE,
                 node: int = cg.NODE, start_timeout_s: float = 20.0, extra_args: list[str] | None = None,
                 pace: float | None = None):
        args = ["--can", "--seed", str(seed), "--can-bitrate", str(bitrate), "--node", str(node)]
        if pace:
            args += ["--pace", repr(float(pace))]
        if motor_path:
            args += ["--motor", str(motor_path)]
        if rig_path:
            args += ["--rig", str(rig_path)]
        self.proc = emu_process.start(args + (extra_args or []))
        self.spec_text = emu_process.wait_for_announcement(self.proc, "can: ", start_timeout_s)
        spec = parse_spec(self.spec_text)
        self.link = open_can(spec, on_close=self.close, name=f"emulator CAN {self.spec_text}")

    def close(self) -> None:
        emu_process.stop(self.proc)


class InProcessCanBus:
    """A python-can-like bus whose other end is the emulated device in this process (no socket).

    The device runs only when the host reads, a chunk of control periods at a time, as with
    pmsm_hil.transport.inproc. `fault` (optional) is called with each frame list on its way to the
    host or the device and returns the frames to deliver (tests corrupt or drop frames with it)."""

    channel_info = "in-process emulator"

    def __init__(self, device, chunk_ticks: int = 400, fault_d2h=None, fault_h2d=None):
        self.dev = device
        self.chunk_ticks = chunk_ticks
        self.fault_d2h = fault_d2h
        self.fault_h2d = fault_h2d
        self._rx: list = []
        self.recorded: list[tuple[float, int, bytes]] | None = None   # set to [] to record (t, id, data)
        self._ts = device.get("ts_s")

    def send(self, msg, timeout=None) -> None:
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

    def recv(self, timeout=None):
        import can
        if not self._rx:
            self._rx = self._run_chunk()[::-1]
            if not self._rx:
                return None
        ident, data = self._rx.pop()
        return can.Message(arbitration_id=ident, data=data, is_extended_id=False, is_rx=True)

    def shutdown(self) -> None:
        pass


def inprocess_can_link(settings: dict[str, float], chunk_ticks: int = 400, device=None, **faults) -> CanLink:
    from pmsm_hil.emulator.fwlib import EmulatedDevice
    dev = device or EmulatedDevice(settings)
    bus = InProcessCanBus(dev, chunk_ticks, **faults)
    return CanLink(bus, node=int(settings.get("can_node", cg.NODE)),
                   bit_rate=float(settings.get("can_bitrate", cg.BITRATE)), name="in-process emulator (CAN)")


def apply_can_rates(profile) -> None:
    """Use the profile's CAN telemetry rates (link.can.*_hz, where set) for a run over CAN."""
    can_cfg = getattr(getattr(profile, "link", None), "can", None)
    if can_cfg is None:
        return
    update = {k: getattr(can_cfg, k) for k in ("fast_hz", "params_hz", "status_hz", "truth_hz")
              if getattr(can_cfg, k, None) is not None}
    tel = profile.telemetry.model_copy(update=update)
    if getattr(can_cfg, "fast_hz", None) is None and tel.fast_hz:
        # not set for CAN: the serial rate, lowered to what fits the bus next to the other streams
        from pmsm_hil.protocol.can_link import can_fast_hz_max
        fit = can_fast_hz_max({"params": tel.params_hz, "status": tel.status_hz,
                               "sim_truth": tel.truth_hz}, profile.control.ts_s,
                              getattr(can_cfg, "bitrate", 1_000_000))
        tel = tel.model_copy(update={"fast_hz": min(tel.fast_hz, fit)})
    profile.telemetry = tel


def open_for_run(spec_text: str | None, profile, rig_path: str | None, seed: int,
                 pace: float | None = None) -> CanLink:
    """`run --can SPEC`: a rig's CAN interface, or (SPEC `emulator` or empty) a started emulator."""
    spec = parse_spec(spec_text)
    can_cfg = getattr(profile.link, "can", None)
    if spec_text is None or "bitrate=" not in (spec_text or ""):
        spec.bitrate = getattr(can_cfg, "bitrate", spec.bitrate)
    if spec_text is None or "node=" not in (spec_text or ""):
        spec.node = getattr(can_cfg, "node", spec.node)
    apply_can_rates(profile)
    if spec.is_emulator:
        return CanEmulator(str(profile.motor.path), rig_path, seed, spec.bitrate, spec.node, pace=pace).link
    return open_can(spec)
