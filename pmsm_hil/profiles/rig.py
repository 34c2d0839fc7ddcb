"""Rig files (profiles/rigs/*.yaml): how the emulator's plant departs from the motor file's model.

A rig is a mapping of named, switchable effects, each with ``enabled`` and its own parameters.
Adding an effect later (saturation, temperature, ...) means: a subclass of ``Effect`` with its
parameters and defaults, one field in ``Effects`` (default: the effect disabled), and one bit in
``EFFECT_BITS`` (the bit the emulator sets in ``/sim/truth.effects`` while the effect is on).
"""
from __future__ import annotations

import math
import os
from typing import Iterator

from pydantic import Field, ValidationError

from ._base import FileModel, StrictModel, default_file, meta_value
from ._source import Problem, ProfileError, Source, read_source, validation_problems

__all__ = ["Rig", "Effect", "Effects", "DeadTime", "AdcNoise", "AdcQuantisation", "Encoder",
           "Friction", "EFFECT_BITS", "load_rig"]


class Effect(StrictModel):
    """One departure of the plant from the nominal model. Listed in the file -> on by default."""

    enabled: bool = Field(True, description="the effect acts on the plant")


class DeadTime(Effect):
    """Inverter non-linearity: on each switching edge of a leg, the leg's voltage follows the phase
    current's sign for dead_time_s (diodes conduct), and the conducting switch or diode drops
    v_drop_v; both oppose the phase current, with the sign smoothed over +-i_dt_a.
    The exact plant model is in docs/plant.md."""

    dead_time_s: float = Field(2.0e-6, ge=0, le=20e-6, description="blanking time per switching edge, s")
    v_drop_v: float = Field(1.0, ge=0, le=20, description="switch/diode on-state drop, V")
    i_dt_a: float = Field(0.5, gt=0, le=50,
                          description="current over which the error changes sign (linear zone), A")


class AdcNoise(Effect):
    """White Gaussian noise on every sampled phase current."""

    i_noise_a: float = Field(0.02, ge=0, le=10, description="rms noise per phase current sample, A")


class AdcQuantisation(Effect):
    """Current ADC resolution: samples are rounded to multiples of adc_lsb_a."""

    adc_lsb_a: float = Field(100.0 / 4096.0, gt=0, le=10,
                             description="one ADC step in A (12-bit over +-50 A = 0.0244 A)")


class Encoder(Effect):
    """Incremental encoder: angle quantised to 4 * lines counts per mechanical revolution, with a
    misalignment between count 0 and the rotor's d axis."""

    lines: int = Field(2500, ge=1, le=1_000_000, description="lines per revolution (counts = 4 lines)")
    offset_rad: float = Field(0.0, ge=-math.pi, le=math.pi,
                              description="electrical angle error of the encoder zero, rad")

    @property
    def counts(self) -> int:
        """Counts per mechanical revolution after x4 quadrature decoding."""
        return 4 * self.lines


class Friction(Effect):
    """Friction beyond the motor file's nominal b_visc_nms / t_coulomb_nm (added to them)."""

    t_coulomb_nm: float = Field(0.05, ge=0, le=1e3, description="extra Coulomb friction, N m")
    b_visc_nms: float = Field(2.0e-4, ge=0, le=1e2, description="extra viscous friction, N m s/rad")


# bit of each effect in /sim/truth.effects and the emulator's effect mask
EFFECT_BITS: dict[str, int] = {
    "dead_time": 0,
    "adc_noise": 1,
    "adc_quantisation": 2,
    "encoder": 3,
    "friction": 4,
}


class Effects(StrictModel):
    """The named effects; one that is not listed in the file is off (ideal plant in that respect)."""

    dead_time: DeadTime = Field(default_factory=lambda: DeadTime(enabled=False))
    adc_noise: AdcNoise = Field(default_factory=lambda: AdcNoise(enabled=False))
    adc_quantisation: AdcQuantisation = Field(default_factory=lambda: AdcQuantisation(enabled=False))
    encoder: Encoder = Field(default_factory=lambda: Encoder(enabled=False))
    friction: Friction = Field(default_factory=lambda: Friction(enabled=False))

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


class Rig(FileModel):
    """The emulator's plant departures (issue 5 extends the effects)."""

    name: str = Field(min_length=1, description="rig name")
    description: str = Field("", description="text")
    v_dc_v: float | None = Field(None, gt=0, le=2000,
                                 description="DC-link voltage of this rig, V (null: the motor's v_dc_v)")
    effects: Effects = Field(default_factory=Effects, description="named effects")

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

    def metadata(self) -> dict[str, str]:
        """Flat string record for the MCAP metadata ("effect.param": value)."""
        out = {"name": self.name, "file": self.path.replace("\\", "/").rsplit("/", 1)[-1],
               "sha256": self.sha256, "v_dc_v": meta_value(self.v_dc_v),
               "effects": ",".join(self.enabled_effects), "effects_mask": str(self.effects_mask)}
        for name, eff in self.effects.items():
            for k, v in eff.model_dump().items():
                out[f"{name}.{k}"] = meta_value(v)
        return out


def _load_rig_source(src: Source) -> tuple[Rig | None, list[Problem]]:
    if src.problems:
        return None, list(src.problems)
    try:
        rig = Rig.model_validate(src.data)
    except ValidationError as e:
        return None, list(src.soft) + validation_problems(e, src, Rig)
    if src.soft:
        return None, list(src.soft)
    rig._path, rig._yaml_text = src.path, src.text
    return rig, []


def load_rig(path: str | os.PathLike | None = None) -> Rig:
    """Load and validate one rig file (None: the shipped profiles/rigs/default.yaml);
    raises ProfileError."""
    path = default_file("rigs/default.yaml") if path is None else os.fspath(path)
    rig, problems = _load_rig_source(read_source(path, what="rig file"))
    if problems:
        raise ProfileError(problems)
    return rig
