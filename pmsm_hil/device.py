"""One factory opens a device for the CLI, the benchmarks and the tests: a rig on a serial port or a
CAN interface, the emulator as a process (pty or CAN), or the emulator in this process.

    link = open_device(DeviceSpec(), profile)                  # the emulator on its pty
    link = open_device(DeviceSpec(can="emulator"), profile)    # ... on CAN (socketcand)
    link = open_device(DeviceSpec(port="/dev/ttyUSB0"), profile)
    link = open_device(DeviceSpec(in_process=True), profile)   # no process, no pty
    session = Session(link)

This is the one place where transports (byte pipes and CAN buses) meet the protocol's links;
neither of those packages imports the other (docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pmsm_hil.protocol import can_generated as cg
from pmsm_hil.protocol.can_link import CanLink, can_fast_hz_max
from pmsm_hil.protocol.link import SerialLink

if TYPE_CHECKING:
    from pmsm_hil.emulator.fwlib import EmulatedDevice
    from pmsm_hil.profiles import Profile
    from pmsm_hil.transport.can_bus import CanSpec, FrameFault


@dataclass
class DeviceSpec:
    port: str | None = None  # serial port of a rig
    can: str | None = None  # a python-can SPEC, or "emulator"/"" for the emulator on CAN
    in_process: bool = False  # the emulator in this process (tests, benchmarks, sweeps)
    baud: int | None = None  # serial bit rate (None: the profile's)
    rig_path: str | None = None  # the emulator's rig file (None: the profile's)
    seed: int = 1  # the emulator's noise seed
    pace: float | None = None  # the emulator at X times real time (None: as fast as it can)
    corrupt_ppm: float = 0.0  # the emulator flips bits on its serial output (tests)
    theta_e0_rad: float = 0.0  # the emulator's rotor angle at the start of a run (sensorless tests)

    @property
    def is_rig(self) -> bool:
        # `emulator,bitrate=N` is the emulator too: its interface is what comes before the options
        interface = None if self.can is None else self.can.split(",", 1)[0].strip()
        return bool(self.port) or (interface is not None and interface not in ("", "emulator"))


def link_options_problem(port: str | None, can: str | None, baud: int | None) -> str | None:
    """What is wrong with a command's --port, --can and --baud taken together, or None: a device
    is reached on one link, and --baud is the serial bit rate (CAN's is SPEC's ``bitrate=``).
    Without this, ``--port /dev/ttyUSB0 --can`` ran the emulator on CAN, the rig never opened."""
    if port and can is not None:
        return (
            f"--port {port} and --can {can or 'emulator'}: give one link, a serial port or a "
            "CAN SPEC (--can alone starts the emulator on CAN)"
        )
    if can is not None and baud is not None:
        return (
            f"--baud {baud} is the serial bit rate; over CAN give it in the SPEC: "
            f"--can {can or 'emulator'},bitrate=N (docs/can.md)"
        )
    return None


def _rig_path(spec: DeviceSpec, profile) -> str | None:
    return spec.rig_path or (str(profile.rig.path) if profile.rig.path else None)


def open_device(spec: DeviceSpec, profile: Profile) -> SerialLink | CanLink:
    """A link to the device that `spec` names, set up for `profile` (its motor and rig for an
    emulator; its CAN rates for a CAN link). Raises TransportError (TransportSpecError for a
    SPEC that cannot be meant)."""
    if spec.can is not None and spec.in_process:
        apply_can_rates(profile)
        settings = emulator_settings_for(profile, spec)
        settings.update(
            can_bitrate=float(profile.link.can.bitrate), can_node=float(profile.link.can.node)
        )
        return inprocess_can_link(settings)
    if spec.can is not None:
        return open_can_for_run(spec, profile)
    baud = spec.baud or profile.link.baud
    if spec.in_process:
        from pmsm_hil.transport.inproc import InProcessTransport

        return SerialLink(InProcessTransport(emulator_settings_for(profile, spec)))
    if spec.port:
        from pmsm_hil.transport.serial_port import SerialTransport

        return SerialLink(SerialTransport(spec.port, baud))
    from pmsm_hil.transport.emulator import EmulatorTransport

    settings, plant = _child_settings(spec, profile, baud)
    return SerialLink(
        EmulatorTransport(
            str(profile.motor.path),
            _rig_path(spec, profile),
            spec.seed,
            baud,
            corrupt_ppm=spec.corrupt_ppm,
            pace=spec.pace,
            settings=settings,
            plant=plant,
        )
    )


def _child_settings(spec: DeviceSpec, profile, baud: int) -> tuple[dict[str, float], str]:
    """The settings the emulator child would build from the motor and rig files it is named
    (the same files, loaded the same way), and its plant line."""
    from pmsm_hil.emulator.settings import emulator_settings
    from pmsm_hil.profiles import load_motor, load_rig

    motor = load_motor(str(profile.motor.path))
    rig_path = _rig_path(spec, profile)
    rig = load_rig(rig_path) if rig_path else load_rig(None)
    settings = emulator_settings(
        motor,
        rig,
        seed=spec.seed,
        baud=baud,
        truth_hz=profile.telemetry.truth_hz,
        ts_s=profile.control.ts_s,
    )
    return settings, f"motor: {motor.name}  rig: {rig.name or 'default'}"


def emulator_settings_for(profile: Profile, spec: DeviceSpec | None = None) -> dict[str, float]:
    """The sim board's settings for an emulator of `profile` (its motor, its rig or spec's)."""
    from pmsm_hil.emulator.settings import emulator_settings
    from pmsm_hil.profiles import load_rig

    spec = spec or DeviceSpec()
    rig = load_rig(spec.rig_path) if spec.rig_path else profile.rig
    s = emulator_settings(
        profile.motor,
        rig,
        seed=spec.seed,
        baud=spec.baud or profile.link.baud,
        truth_hz=profile.telemetry.truth_hz,
        ts_s=profile.control.ts_s,
    )
    if spec.theta_e0_rad:
        s["theta_e0_rad"] = spec.theta_e0_rad
    return s


# ----------------------------------------------------------------------------------- CAN


def open_can(
    bus_spec: CanSpec, on_close: Callable[[], None] | None = None, name: str | None = None
) -> CanLink:
    """The protocol's CAN link on a python-can bus named by a parsed CanSpec."""
    from pmsm_hil.transport.can_bus import open_bus

    bitrate = bus_spec.bitrate if bus_spec.bitrate is not None else cg.BITRATE
    node = bus_spec.node if bus_spec.node is not None else cg.NODE
    bus_spec.bitrate, bus_spec.node = bitrate, node
    bus = open_bus(bus_spec)
    return CanLink(
        bus,
        node=node,
        bit_rate=bitrate,
        name=name or f"CAN {bus_spec.text()} node {node}",
        on_close=on_close,
    )


def inprocess_can_link(
    settings: dict[str, float],
    chunk_ticks: int = 400,
    device: EmulatedDevice | None = None,
    **faults: FrameFault | None,
) -> CanLink:
    """The emulated device in this process behind a CAN link (no socket); `faults` as
    InProcessCanBus's fault_d2h/fault_h2d hooks."""
    from pmsm_hil.emulator.fwlib import EmulatedDevice
    from pmsm_hil.transport.can_bus import InProcessCanBus

    dev = device or EmulatedDevice(settings)
    bus = InProcessCanBus(dev, chunk_ticks, **faults)
    return CanLink(
        bus,
        node=int(settings.get("can_node", cg.NODE)),
        bit_rate=float(settings.get("can_bitrate", cg.BITRATE)),
        name="in-process emulator (CAN)",
    )


def apply_can_rates(profile: Profile) -> None:
    """Use the profile's CAN telemetry rates (link.can.*_hz, where set) for a run over CAN; the
    fast-frame rate left unset is the serial one, lowered to what fits beside the other streams."""
    can_cfg = profile.link.can
    update = {
        k: getattr(can_cfg, k)
        for k in ("fast_hz", "params_hz", "status_hz", "truth_hz", "est_hz")
        if getattr(can_cfg, k) is not None
    }
    tel = profile.telemetry.model_copy(update=update)
    if can_cfg.fast_hz is None and tel.fast_hz:
        others = {"params": tel.params_hz, "status": tel.status_hz, "sim_truth": tel.truth_hz}
        if profile.control.angle_src != "encoder":
            others["telem_est"] = tel.est_hz
        fit = can_fast_hz_max(others, profile.control.ts_s, can_cfg.bitrate)
        tel = tel.model_copy(update={"fast_hz": min(tel.fast_hz, fit)})
    profile.telemetry = tel


def open_can_for_run(spec: DeviceSpec, profile: Profile) -> CanLink:
    """`run --can SPEC`: a rig's CAN interface, or (SPEC `emulator` or empty) a started emulator.
    The profile's link.can bit rate and node apply unless SPEC gives them."""
    from pmsm_hil.transport.can_bus import CanEmulator, parse_spec

    bus_spec = parse_spec(spec.can)
    if bus_spec.bitrate is None:
        bus_spec.bitrate = profile.link.can.bitrate
    if bus_spec.node is None:
        bus_spec.node = profile.link.can.node
    # the rates fit the bus in use: SPEC's bit rate, not the profile's (a 500 kbit/s bus given
    # the 1 Mbit/s plan dropped a third of the telemetry in the device)
    can_cfg = profile.link.can.model_copy(
        update={"bitrate": bus_spec.bitrate, "node": bus_spec.node}
    )
    profile.link = profile.link.model_copy(update={"can": can_cfg})
    apply_can_rates(profile)
    if bus_spec.is_emulator:
        emu = CanEmulator(
            str(profile.motor.path),
            _rig_path(spec, profile),
            spec.seed,
            bus_spec.bitrate,
            bus_spec.node,
            pace=spec.pace,
            extra_args=["--truth-hz", repr(float(profile.telemetry.truth_hz))],
        )
        try:
            return open_can(emu.spec, on_close=emu.close, name=f"emulator CAN {emu.spec_text}")
        except BaseException:
            emu.close()
            raise
    return open_can(bus_spec)
