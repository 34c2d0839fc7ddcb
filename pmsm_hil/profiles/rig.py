"""Rig files (profiles/rigs/*.yaml): how the emulator's plant departs from the motor file's model.

A rig is a mapping of named, switchable effects, each with ``enabled`` and its own parameters.
Adding an effect later (saturation, temperature, ...) means: a subclass of ``Effect`` with its
parameters and defaults, one field in ``Effects`` (default: the effect disabled), and one bit in
``EFFECT_BITS`` (the bit the emulator sets in ``/sim/truth.effects`` while the effect is on).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field, ValidationError

from ._base import FileModel, StrictModel, default_file, meta_value
from ._source import Problem, ProfileError, Source, read_source
from ._validation import validation_problems
from .shipped import in_file

if TYPE_CHECKING:
    from .fluxmap import FluxMap

__all__ = [
    "EFFECT_BITS",
    "AdcNoise",
    "AdcQuantisation",
    "Cogging",
    "DcLink",
    "DeadTime",
    "Delay",
    "Effect",
    "Effects",
    "Encoder",
    "FluxHarmonics",
    "Friction",
    "IronLoss",
    "Rig",
    "Saturation",
    "SensorGain",
    "SensorOffset",
    "Thermal",
    "load_rig",
    "plant_problems",
]

# limits of the emulated plant (firmware/sim/plant.h; tests/test_rig_checks.py reads the header)
PLANT_THERMAL_DIV = 16  # the thermal network steps every PLANT_THERMAL_DIV control periods
PLANT_DELAY_RING = 32  # sample_delay_s <= (PLANT_DELAY_RING - 3) ts_s
COG_ORDER_MAX = 1000  # cogging periods per electrical revolution (plant_cfg_check)


class Effect(StrictModel):
    """One departure of the plant from the nominal model. Listed in the file -> on by default."""

    enabled: bool = Field(True, description="the effect acts on the plant")


class DeadTime(Effect):
    """Inverter non-linearity: on each switching edge of a leg, the leg's voltage follows the phase
    current's sign for dead_time_s (diodes conduct), and the conducting switch or diode drops
    v_drop_v; both oppose the phase current, with the sign smoothed over +-i_dt_a.
    The exact plant model is in docs/plant.md."""

    dead_time_s: float = Field(
        2.0e-6, ge=0, le=20e-6, description="blanking time per switching edge, s"
    )
    v_drop_v: float = Field(1.0, ge=0, le=20, description="switch/diode on-state drop, V")
    i_dt_a: float = Field(
        0.5, gt=0, le=50, description="current over which the error changes sign (linear zone), A"
    )


class AdcNoise(Effect):
    """White Gaussian noise on every sampled phase current."""

    i_noise_a: float = Field(0.02, ge=0, le=10, description="rms noise per phase current sample, A")


class AdcQuantisation(Effect):
    """Current ADC resolution: samples are rounded to multiples of adc_lsb_a."""

    adc_lsb_a: float = Field(
        100.0 / 4096.0, gt=0, le=10, description="one ADC step in A (12-bit over +-50 A = 0.0244 A)"
    )


class Encoder(Effect):
    """Incremental encoder: angle quantised to 4 * lines counts per mechanical revolution, with a
    misalignment between count 0 and the rotor's d axis."""

    lines: int = Field(
        2500, ge=1, le=1_000_000, description="lines per revolution (counts = 4 lines)"
    )
    offset_e_rad: float = Field(
        0.0, ge=-math.pi, le=math.pi, description="electrical angle error of the encoder zero, rad"
    )
    lines_told: int | None = Field(
        None,
        ge=1,
        le=1_000_000,
        description="lines the firmware is told (enc_counts = 4 lines_told; null: lines): a rig "
        "file that misstates its encoder, to rehearse that mistake on the emulator",
    )

    @property
    def counts(self) -> int:
        """Counts per mechanical revolution after x4 quadrature decoding."""
        return 4 * self.lines


class Friction(Effect):
    """Friction beyond the motor file's nominal b_visc_nms / t_coulomb_nm (added to them)."""

    t_coulomb_nm: float = Field(0.05, ge=0, le=1e3, description="extra Coulomb friction, N m")
    b_visc_nms: float = Field(2.0e-4, ge=0, le=1e2, description="extra viscous friction, N m s/rad")


class Saturation(Effect):
    """Magnetic saturation and cross-saturation: the flux linkages psi_d(i_d, i_q), psi_q(i_d, i_q)
    from a flux map on a regular current grid (CSV with columns i_d_a, i_q_a, psi_d_wb, psi_q_wb;
    nodes outside the measured region are extrapolated, docs/rigs.md). The plant uses the map's
    incremental inductances in its dynamics and its psi_d(0, 0) as the magnet flux."""

    map: str | None = Field(None, description="flux-map CSV, relative to the rig file")


class Thermal(Effect):
    """Two-node thermal network (winding, magnet) heated by the copper and iron losses; R and psi_f
    follow the temperatures. The motor file's r_s_ohm and psi_f_wb hold at temp_ref_c."""

    temp_ambient_c: float = Field(25.0, ge=-50, le=200, description="ambient temperature, degC")
    temp_winding_c: float = Field(
        25.0, ge=-50, le=250, description="initial winding temperature, degC"
    )
    temp_magnet_c: float = Field(
        25.0, ge=-50, le=250, description="initial magnet temperature, degC"
    )
    temp_ref_c: float = Field(
        25.0,
        ge=-50,
        le=250,
        description="temperature at which the motor file's R and psi_f hold, degC",
    )
    alpha_r_per_k: float = Field(
        0.00393, ge=0, le=0.01, description="resistance coefficient (copper), 1/K"
    )
    alpha_psi_per_k: float = Field(
        -0.001, ge=-0.01, le=0, description="magnet flux coefficient (NdFeB), 1/K"
    )
    c_winding_j_k: float = Field(
        1500.0, gt=0, le=1e6, description="heat capacity of winding + stator, J/K"
    )
    c_magnet_j_k: float = Field(
        600.0, gt=0, le=1e6, description="heat capacity of rotor + magnets, J/K"
    )
    r_wa_k_w: float = Field(
        0.4, gt=0, le=100, description="thermal resistance winding -> ambient, K/W"
    )
    r_wm_k_w: float = Field(
        0.5, gt=0, le=100, description="thermal resistance winding -> magnet, K/W"
    )
    r_ma_k_w: float = Field(
        1.0, gt=0, le=100, description="thermal resistance magnet -> ambient, K/W"
    )
    r_fe_heat_ohm: float = Field(
        0.0,
        ge=0,
        le=1e6,
        description="iron-loss resistance for the heating when the iron_loss "
        "effect is off (0: no iron-loss heating), ohm",
    )


class FluxHarmonics(Effect):
    """5th and 7th harmonics of the magnet flux (so of the back-EMF); a 6th harmonic in dq."""

    emf5_rel: float = Field(
        0.02,
        ge=-0.5,
        le=0.5,
        description="5th harmonic of the phase back-EMF relative to the fundamental",
    )
    emf7_rel: float = Field(
        0.01,
        ge=-0.5,
        le=0.5,
        description="7th harmonic of the phase back-EMF relative to the fundamental",
    )


class Cogging(Effect):
    """Cogging torque T = amplitude_nm sin(periods_per_rev theta_m + phase_rad)."""

    amplitude_nm: float = Field(0.05, ge=0, le=1e3, description="cogging torque amplitude, N m")
    periods_per_rev: int = Field(
        24,
        ge=1,
        le=10_000,
        description="cogging periods per mechanical revolution, lcm(slots, 2p); "
        "a multiple of the pole pairs",
    )
    phase_rad: float = Field(0.0, ge=-math.pi, le=math.pi, description="phase, rad")


class SensorOffset(Effect):
    """DC offset of each phase-current channel."""

    i_a_a: float = Field(0.05, ge=-50, le=50, description="offset of channel a, A")
    i_b_a: float = Field(-0.03, ge=-50, le=50, description="offset of channel b, A")
    i_c_a: float = Field(0.0, ge=-50, le=50, description="offset of channel c, A")


class SensorGain(Effect):
    """Gain of each phase-current channel (mismatch between the phases)."""

    i_a_gain: float = Field(1.0, ge=0.5, le=1.5, description="gain of channel a")
    i_b_gain: float = Field(1.02, ge=0.5, le=1.5, description="gain of channel b")
    i_c_gain: float = Field(0.99, ge=0.5, le=1.5, description="gain of channel c")


class Delay(Effect):
    """Delays beyond the one control period that the firmware compensates."""

    sample_delay_s: float = Field(
        0.0,
        ge=0,
        le=5e-4,
        description="the currents are sampled this long before the period "
        "boundary (filter and conversion latency), s",
    )
    pwm_delay_periods: int = Field(
        1, ge=0, le=16, description="the switch command takes effect this many periods later"
    )


class DcLink(Effect):
    """DC link fed by a six-pulse diode rectifier (or a DC source) through a source resistance,
    buffered by a capacitor; the firmware sees the measured DC voltage."""

    r_source_ohm: float = Field(
        0.5, gt=0, le=100, description="source resistance (grid, choke, rectifier), ohm"
    )
    c_dc_f: float = Field(1.0e-3, gt=0, le=1, description="DC-link capacitance, F")
    rectifier: bool = Field(
        True, description="six-pulse diode rectifier from the grid (false: a DC source)"
    )
    grid_hz: float = Field(50.0, ge=0, le=1000, description="grid frequency, Hz")


class IronLoss(Effect):
    """Iron loss as an equivalent resistance across the speed voltage (i_fe = e / R_fe)."""

    r_fe_ohm: float = Field(300.0, gt=0, le=1e6, description="equivalent iron-loss resistance, ohm")


class MotorDeviation(Effect):
    """The motor on the rig departs from its motor file (a production spread, a datasheet's
    tolerance): its R, L_d, L_q and psi_f are the file's times these factors, and a flux map's
    small-current values likewise (the map scaled, docs/rigs.md). The firmware is told the file's
    values, as a drive's parameters come from the datasheet until commissioning measures them."""

    r_s_factor: float = Field(1.0, ge=0.5, le=2.0, description="plant R / the motor file's")
    l_d_factor: float = Field(1.0, ge=0.5, le=2.0, description="plant L_d / the motor file's")
    l_q_factor: float = Field(1.0, ge=0.5, le=2.0, description="plant L_q / the motor file's")
    psi_f_factor: float = Field(1.0, ge=0.5, le=2.0, description="plant psi_f / the motor file's")
    pole_pairs: int | None = Field(
        None,
        ge=1,
        le=100,
        description="plant pole pairs (null: the motor file's): a motor file with a wrong "
        "pole_pairs, to rehearse that mistake on the emulator",
    )


# bit of each effect in /sim/truth.effects and the emulator's effect mask
EFFECT_BITS: dict[str, int] = {
    "dead_time": 0,
    "adc_noise": 1,
    "adc_quantisation": 2,
    "encoder": 3,
    "friction": 4,
    "saturation": 5,
    "thermal": 6,
    "flux_harmonics": 7,
    "cogging": 8,
    "sensor_offset": 9,
    "sensor_gain": 10,
    "delay": 11,
    "dc_link": 12,
    "iron_loss": 13,
    "motor_deviation": 14,
}


class Effects(StrictModel):
    """The named effects; one that is not listed in the file is off (ideal plant in that respect)."""

    dead_time: DeadTime = Field(default_factory=lambda: DeadTime(enabled=False))
    adc_noise: AdcNoise = Field(default_factory=lambda: AdcNoise(enabled=False))
    adc_quantisation: AdcQuantisation = Field(
        default_factory=lambda: AdcQuantisation(enabled=False)
    )
    encoder: Encoder = Field(default_factory=lambda: Encoder(enabled=False))
    friction: Friction = Field(default_factory=lambda: Friction(enabled=False))
    saturation: Saturation = Field(default_factory=lambda: Saturation(enabled=False))
    thermal: Thermal = Field(default_factory=lambda: Thermal(enabled=False))
    flux_harmonics: FluxHarmonics = Field(default_factory=lambda: FluxHarmonics(enabled=False))
    cogging: Cogging = Field(default_factory=lambda: Cogging(enabled=False))
    sensor_offset: SensorOffset = Field(default_factory=lambda: SensorOffset(enabled=False))
    sensor_gain: SensorGain = Field(default_factory=lambda: SensorGain(enabled=False))
    delay: Delay = Field(default_factory=lambda: Delay(enabled=False))
    dc_link: DcLink = Field(default_factory=lambda: DcLink(enabled=False))
    iron_loss: IronLoss = Field(default_factory=lambda: IronLoss(enabled=False))
    motor_deviation: MotorDeviation = Field(default_factory=lambda: MotorDeviation(enabled=False))

    def items(self) -> Iterator[tuple[str, Effect]]:
        for name in type(self).model_fields:
            yield name, getattr(self, name)

    def __getitem__(self, name: str) -> Effect:
        if name not in type(self).model_fields:
            raise KeyError(name)
        return getattr(self, name)

    def names(self) -> list[str]:
        return list(type(self).model_fields)

    def get(self, name: str, default: Effect | None = None) -> Effect | None:
        """The effect ``name`` (enabled or not), or ``default`` for an unknown name."""
        return getattr(self, name) if name in type(self).model_fields else default


class Wiring(StrictModel):
    """How the motor is connected to the inverter: a wiring fault that commissioning must catch
    (docs/commissioning.md). Not a plant effect: the default is the correct wiring."""

    phases: Literal["abc", "acb"] = Field(
        "abc",
        description="abc: as labelled; acb: phases b and c swapped between inverter and motor",
    )
    motor_connected: bool = Field(True, description="false: the motor cable is not connected")


class Rig(FileModel):
    """The emulator's plant departures (issue 5 extends the effects)."""

    name: str = Field(min_length=1, description="rig name")
    description: str = Field("", description="text")
    v_dc_v: float | None = Field(
        None, gt=0, le=2000, description="DC-link voltage of this rig, V (null: the motor's v_dc_v)"
    )
    effects: Effects = Field(default_factory=Effects, description="named effects")
    wiring: Wiring = Field(default_factory=Wiring, description="wiring faults (tests)")

    def enabled(self, name: str) -> bool:
        return bool(self.effects[name].enabled)

    @property
    def enabled_effects(self) -> list[str]:
        return [n for n, e in self.effects.items() if e.enabled]

    @property
    def effects_mask(self) -> int:
        """uint32 with bit EFFECT_BITS[name] set for each enabled effect."""
        mask = 0
        for name, eff in self.effects.items():
            if eff.enabled:
                mask |= 1 << EFFECT_BITS[name]
        return mask

    def plant_pole_pairs(self, motor_pole_pairs: int) -> int:
        """The emulated motor's pole pairs: the motor file's unless motor_deviation says
        otherwise."""
        dev = self.effects.motor_deviation
        return dev.pole_pairs if dev.enabled and dev.pole_pairs else motor_pole_pairs

    def plant_factors(self) -> dict[str, float]:
        """motor_deviation's factors on psi_f and R, keyed as /sim/truth's fields ({} when off):
        the emulator's plant is the motor file's times them."""
        dev = self.effects.motor_deviation
        return {"psi_f_wb": dev.psi_f_factor, "r_s_ohm": dev.r_s_factor} if dev.enabled else {}

    def map_path(self) -> str | None:
        """The saturation flux map's path (relative to the rig file's directory; where nothing is
        there, the shipped map of that name), or None."""
        sat = self.effects.saturation
        if not sat.enabled or not sat.map:
            return None
        if os.path.isabs(sat.map):
            return sat.map
        rel = os.path.normpath(os.path.join(os.path.dirname(self.path or "."), sat.map))
        return in_file(rel, sat.map, "map")[0]

    def flux_map(self) -> FluxMap | None:
        """The saturation effect's FluxMap (pmsm_hil.profiles.fluxmap), or None when off."""
        path = self.map_path()
        if path is None:
            return None
        from .fluxmap import load_flux_map

        return load_flux_map(path)

    def metadata(self) -> dict[str, str]:
        """Flat string record for the MCAP metadata ("effect.param": value)."""
        out = {
            "name": self.name,
            "file": self.path.replace("\\", "/").rsplit("/", 1)[-1],
            "sha256": self.sha256,
            "v_dc_v": meta_value(self.v_dc_v),
            "effects": ",".join(self.enabled_effects),
            "effects_mask": str(self.effects_mask),
        }
        for name, eff in self.effects.items():
            for k, v in eff.model_dump().items():
                out[f"{name}.{k}"] = meta_value(v)
        return out

    def effective_metadata(self, motor: Any = None) -> dict[str, str]:
        """The effects in force and their sizes, only those enabled ("effect.param": value), with
        what the flux map resolves to (file, sha256, grid, psi_f, and its scaling when it is
        another motor's: `motor` is the plant's nominal machine): the MCAP record "rig_effects"."""
        out = {
            "rig": self.name,
            "effects": ",".join(self.enabled_effects),
            "effects_mask": str(self.effects_mask),
        }
        for name, eff in self.effects.items():
            if not eff.enabled:
                continue
            for k, v in eff.model_dump().items():
                if k != "enabled":
                    out[f"{name}.{k}"] = meta_value(v)
        fm = self.flux_map() if self.effects.saturation.enabled else None
        if fm is not None:
            out.update({f"saturation.{k}": v for k, v in fm.metadata().items()})
            if motor is not None:
                from .fluxmap import for_motor

                _, scaled = for_motor(fm, motor.psi_f_wb, motor.l_d_h, motor.l_q_h)
                out.update({f"saturation.scaled_{k}": repr(v) for k, v in scaled.items()})
        return out


def _load_rig_source(src: Source) -> tuple[Rig | None, list[Problem]]:
    """The rig and its problems: no rig when a field is invalid; the rig with its flux map's
    problem when only the map cannot be used (not to be run: the caller checks the problems)."""
    if src.problems:
        return None, list(src.problems)
    try:
        rig = Rig.model_validate(src.data)
    except ValidationError as e:
        return None, list(src.soft) + validation_problems(e, src, Rig)
    if src.soft:
        return None, list(src.soft)
    rig._path, rig._yaml_text = src.path, src.text
    sat = rig.effects.saturation
    if sat.enabled:
        loc = ("effects", "saturation", "map")
        # a map problem comes with the rig, whose other fields are valid: the checks against the
        # motor (plant_problems) then report in the same pass (only the map is not loaded)
        if not sat.map:
            return rig, [
                src.problem(
                    ("effects", "saturation"),
                    "has no map: give map: FILE.csv (a flux map, docs/rigs.md)",
                )
            ]
        from .fluxmap import FluxMapError, load_flux_map

        map_path = rig.map_path()
        assert map_path is not None  # saturation is on and names a map
        try:
            load_flux_map(map_path)
        except (OSError, FluxMapError) as e:
            return rig, [src.problem(loc, f"names a flux map that cannot be used: {e}", sat.map)]
    return rig, []


def plant_problems(src: Source, rig: Rig, pole_pairs: int, ts_s: float | None) -> list[Problem]:
    """The checks of the emulated plant (firmware/sim/plant.c plant_cfg_check) that depend on the
    motor's pole pairs or the profile's control period, as problems of the rig file ``src``
    (ts_s None: the period is itself wrong, those checks are skipped)."""
    out: list[Problem] = []
    eff = rig.effects
    cg = eff.cogging
    if cg.enabled:
        loc = ("effects", "cogging", "periods_per_rev")
        if cg.periods_per_rev % pole_pairs:
            out.append(
                src.problem(
                    loc,
                    f"is not a multiple of the motor's pole_pairs {pole_pairs}",
                    cg.periods_per_rev,
                )
            )
        elif cg.amplitude_nm != 0 and cg.periods_per_rev // pole_pairs > COG_ORDER_MAX:
            out.append(
                src.problem(
                    loc,
                    f"gives {cg.periods_per_rev // pole_pairs} periods per electrical "
                    f"revolution, above the plant's {COG_ORDER_MAX} "
                    f"(pole_pairs {pole_pairs})",
                    cg.periods_per_rev,
                )
            )
    if ts_s is None:
        return out
    dt = eff.dead_time
    if dt.enabled and not dt.dead_time_s < ts_s:
        out.append(
            src.problem(
                ("effects", "dead_time", "dead_time_s"),
                f"is not shorter than the control period control.ts_s = {ts_s:g} s",
                dt.dead_time_s,
            )
        )
    dl = eff.delay
    if dl.enabled and not dl.sample_delay_s <= (PLANT_DELAY_RING - 3) * ts_s:
        out.append(
            src.problem(
                ("effects", "delay", "sample_delay_s"),
                f"is longer than {PLANT_DELAY_RING - 3} control periods "
                f"({(PLANT_DELAY_RING - 3) * ts_s:g} s at control.ts_s = {ts_s:g} s)",
                dl.sample_delay_s,
            )
        )
    th = eff.thermal
    if th.enabled:
        step = PLANT_THERMAL_DIV * ts_s
        for c_name, r_name in (
            ("c_winding_j_k", "r_wm_k_w"),
            ("c_magnet_j_k", "r_wm_k_w"),
            ("c_winding_j_k", "r_wa_k_w"),
            ("c_magnet_j_k", "r_ma_k_w"),
        ):
            c, r = getattr(th, c_name), getattr(th, r_name)
            if not step < 0.2 * c * r:
                out.append(
                    src.problem(
                        ("effects", "thermal", c_name),
                        f"gives with {r_name} = {r:g} K/W a time constant of {c * r:g} s, "
                        f"shorter than 5 thermal steps ({5 * step:g} s: "
                        f"{PLANT_THERMAL_DIV} x control.ts_s)",
                        c,
                    )
                )
                break
    return out


def load_rig(path: str | os.PathLike | None = None) -> Rig:
    """Load and validate one rig file (None: the shipped profiles/rigs/default.yaml);
    raises ProfileError."""
    path = default_file("rigs/default.yaml") if path is None else os.fspath(path)
    rig, problems = _load_rig_source(read_source(path, what="rig file"))
    if rig is None or problems:
        raise ProfileError(problems)
    return rig
