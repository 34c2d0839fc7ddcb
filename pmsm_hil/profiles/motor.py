"""Motor files (profiles/motors/*.yaml): the nominal machine model and its protection limits."""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, Any

from pydantic import Field, ValidationError

from ._base import FileModel, StrictModel, default_file, meta_value, num
from ._source import Problem, ProfileError, Source, fmt_num, read_source
from ._validation import validation_problems
from .shipped import in_file

if TYPE_CHECKING:
    from .fluxmap import FluxMap

__all__ = ["CurrentSensors", "Motor", "load_motor", "mtpa_currents", "mtpa_torque_nm"]


def mtpa_currents(i_s_a: float, psi_f_wb: float, l_d_h: float, l_q_h: float) -> tuple[float, float]:
    """(i_d_a, i_q_a) of maximum torque per ampere for current magnitude ``i_s_a`` (i_q >= 0).

    From dT/d(beta) = 0 with T = 1.5 p (psi_f i_q + (L_d - L_q) i_d i_q):
    i_d = (psi_f - sqrt(psi_f^2 + 8 (L_q - L_d)^2 i_s^2)) / (4 (L_q - L_d)); i_d = 0 when L_d = L_q.
    """
    d_l = l_q_h - l_d_h
    if abs(d_l) < 1e-12:
        return 0.0, float(i_s_a)
    i_d = (psi_f_wb - math.sqrt(psi_f_wb**2 + 8.0 * d_l**2 * i_s_a**2)) / (4.0 * d_l)
    i_q = math.sqrt(max(i_s_a**2 - i_d**2, 0.0))
    return i_d, i_q


def mtpa_torque_nm(
    i_s_a: float, pole_pairs: int, psi_f_wb: float, l_d_h: float, l_q_h: float
) -> float:
    """Electromagnetic torque for current magnitude ``i_s_a`` on the MTPA trajectory."""
    i_d, i_q = mtpa_currents(i_s_a, psi_f_wb, l_d_h, l_q_h)
    return 1.5 * pole_pairs * (psi_f_wb * i_q + (l_d_h - l_q_h) * i_d * i_q)


class CurrentSensors(StrictModel):
    """Current-sensor calibration measured by commissioning (docs/commissioning.md): the firmware
    subtracts the offset and divides by (1 + gain error) before it uses a sample."""

    i_a_offset_a: float = Field(0.0, ge=-10, le=10, description="phase-a sensor offset, A")
    i_b_offset_a: float = Field(0.0, ge=-10, le=10, description="phase-b sensor offset, A")
    i_c_offset_a: float = Field(0.0, ge=-10, le=10, description="phase-c sensor offset, A")
    i_a_gain_err: float = Field(
        0.0, ge=-0.2, le=0.2, description="phase-a gain relative to the mean of the three, -1"
    )
    i_b_gain_err: float = Field(0.0, ge=-0.2, le=0.2, description="phase-b gain error")
    i_c_gain_err: float = Field(0.0, ge=-0.2, le=0.2, description="phase-c gain error")


class Motor(FileModel):
    """Nominal PMSM model (what the firmware's predictor and the host's "sim" use) and limits."""

    name: str = Field(min_length=1, description="motor name")
    pole_pairs: int = Field(ge=1, le=100, description="pole pairs p")
    r_s_ohm: float = Field(gt=0, le=1000, description="stator resistance per phase, ohm")
    l_d_h: float = Field(gt=0, le=10, description="d-axis inductance, H")
    l_q_h: float = Field(gt=0, le=10, description="q-axis inductance, H")
    psi_f_wb: float = Field(gt=0, le=100, description="permanent-magnet flux linkage, Wb")
    j_kgm2: float = Field(gt=0, le=1e4, description="rotor (+ coupled load) inertia, kg m^2")
    b_visc_nms: float = Field(0.0, ge=0, le=1e3, description="viscous friction, N m s/rad")
    t_coulomb_nm: float = Field(0.0, ge=0, le=1e4, description="Coulomb friction, N m")
    v_dc_v: float = Field(gt=0, le=2000, description="nominal DC-link voltage, V")
    i_max_a: float = Field(gt=0, le=10000, description="current limit of the controller, A")
    i_trip_a: float = Field(gt=0, le=10000, description="over-current trip, A (> i_max_a)")
    speed_max_rpm: float = Field(gt=0, le=1e6, description="speed reference limit, r/min")
    speed_trip_rpm: float = Field(
        gt=0, le=1e6, description="over-speed trip, r/min (> speed_max_rpm)"
    )
    torque_max_nm: float = Field(gt=0, le=1e6, description="load/torque limit, N m")
    v_dc_min_v: float = Field(gt=0, le=2000, description="DC-link under-voltage trip, V")
    v_dc_max_v: float = Field(gt=0, le=2000, description="DC-link over-voltage trip, V")
    dead_time_s: float = Field(
        0.0,
        ge=0,
        le=20e-6,
        description="nominal inverter dead time that the firmware compensates, s",
    )
    v_drop_v: float = Field(
        0.0, ge=0, le=20, description="nominal switch/diode drop that the firmware compensates, V"
    )
    i_dt_a: float = Field(
        0.0,
        ge=0,
        le=20,
        description="nominal current band of the dead-time distortion around the "
        "current zero crossing (0: ideal sign), A",
    )
    enc_offset_e_rad: float = Field(
        0.0,
        ge=-7,
        le=7,
        description="electrical angle of the rotor's d axis at encoder count 0, rad "
        "(commissioning measures it; 0: the encoder is aligned)",
    )
    current_sensors: CurrentSensors | None = Field(
        None, description="current-sensor calibration from commissioning (none: raw samples)"
    )
    commissioning: dict[str, Any] | None = Field(
        None,
        description="what commissioning measured: date, device, and each quantity with its "
        "spread (written by `pmsm-hil commission`, docs/commissioning.md)",
    )
    flux_map: str | None = Field(
        None,
        description="the motor's measured flux map (CSV, relative to the motor file; "
        "docs/rigs.md): the emulator's magnetics when the rig has no saturation effect, and "
        "the sensorless estimator's inverse incremental inductances and polarity signature",
    )
    hybrid_pll_on_rpm: float = Field(
        150.0,
        gt=0,
        le=1e5,
        description="hybrid angle source: below this speed the ripple PLL carries the angle, r/min",
    )
    hybrid_mras_on_rpm: float = Field(
        250.0,
        gt=0,
        le=1e5,
        description="hybrid angle source: above this speed the MRAS carries it, r/min "
        "(> hybrid_pll_on_rpm: the band between is the hysteresis)",
    )
    hybrid_blend_s: float = Field(
        0.02, gt=0, le=1, description="hybrid angle source: time of a handover, s"
    )
    polarity_pulse_a: float | None = Field(
        None,
        gt=0,
        le=10000,
        description="d-axis current of the start-up polarity pulses, A (null: half of i_max_a)",
    )
    ripple_pll_excite_a: float | None = Field(
        None,
        ge=0,
        le=10000,
        description="ripple PLL: amplitude of the d-axis current that alternates sign every "
        "control period while it closes the loop, A (null: a tenth of i_max_a; 0: none, only a "
        "1 A square wave at 1 kHz when the ripple is too small; docs/sensorless.md)",
    )
    if_start_current_a: float | None = Field(
        None,
        gt=0,
        le=10000,
        description="MRAS angle source: current of the current-frequency (I/f) start from "
        "standstill, A (null: no I/f start; docs/sensorless.md)",
    )
    if_start_accel_rpm_s: float = Field(
        200.0, gt=0, le=1e6, description="I/f start: acceleration of the open-loop angle, r/min/s"
    )
    if_handover_rpm: float = Field(
        150.0,
        gt=0,
        le=1e5,
        description="I/f start: the speed from which the MRAS may take the angle over, r/min",
    )
    source: str = Field("", description="where the numbers come from")

    # ------------------------------------------------------------------ derived quantities
    def mtpa_currents(self, i_s_a: float) -> tuple[float, float]:
        return mtpa_currents(i_s_a, self.psi_f_wb, self.l_d_h, self.l_q_h)

    def torque_mtpa_nm(self, i_s_a: float) -> float:
        return mtpa_torque_nm(i_s_a, self.pole_pairs, self.psi_f_wb, self.l_d_h, self.l_q_h)

    def flux_map_path(self) -> str | None:
        """The motor's flux map path (relative to the motor file's directory; where nothing is
        there, the shipped map of that name), or None."""
        if not self.flux_map:
            return None
        if os.path.isabs(self.flux_map):
            return self.flux_map
        rel = os.path.normpath(os.path.join(os.path.dirname(self.path or "."), self.flux_map))
        return in_file(rel, self.flux_map, "map")[0]

    def load_flux_map(self) -> FluxMap | None:
        """The motor's FluxMap (pmsm_hil.profiles.fluxmap), or None."""
        path = self.flux_map_path()
        if path is None:
            return None
        from .fluxmap import load_flux_map

        return load_flux_map(path)

    @property
    def speed_max_rad_s(self) -> float:
        """Mechanical speed limit in rad/s."""
        return self.speed_max_rpm * math.pi / 30.0

    def metadata(self) -> dict[str, str]:
        """Flat string record for the MCAP metadata."""
        out = {
            k: meta_value(v)
            for k, v in self.model_dump().items()
            if k not in ("commissioning", "current_sensors", "enc_offset_e_rad")
            or v not in (None, 0.0)
        }
        out["file"] = self.path.replace("\\", "/").rsplit("/", 1)[-1]
        out["sha256"] = self.sha256
        return out


def motor_checks(src: Source) -> list[Problem]:
    """Relations between fields (each reported at the line of the field that breaks it)."""
    d = src.data
    out: list[Problem] = []
    i_max, i_trip = num(d, "i_max_a"), num(d, "i_trip_a")
    if i_max and i_trip is not None and i_trip <= i_max:
        out.append(src.problem(("i_trip_a",), f"must be above i_max_a {fmt_num(i_max)} A", i_trip))
    s_max, s_trip = num(d, "speed_max_rpm"), num(d, "speed_trip_rpm")
    if s_max and s_trip is not None and s_trip <= s_max:
        out.append(
            src.problem(
                ("speed_trip_rpm",), f"must be above speed_max_rpm {fmt_num(s_max)} r/min", s_trip
            )
        )
    v, v_min, v_max = num(d, "v_dc_v"), num(d, "v_dc_min_v"), num(d, "v_dc_max_v")
    if v is not None and v_min is not None and v_min >= v:
        out.append(src.problem(("v_dc_min_v",), f"must be below v_dc_v {fmt_num(v)} V", v_min))
    if v is not None and v_max is not None and v_max <= v:
        out.append(src.problem(("v_dc_max_v",), f"must be above v_dc_v {fmt_num(v)} V", v_max))
    p, psi, l_d, l_q, t_max = (
        num(d, k) for k in ("pole_pairs", "psi_f_wb", "l_d_h", "l_q_h", "torque_max_nm")
    )
    pll_on, mras_on = num(d, "hybrid_pll_on_rpm"), num(d, "hybrid_mras_on_rpm")
    if pll_on is not None and mras_on is not None and mras_on <= pll_on:
        out.append(
            src.problem(
                ("hybrid_mras_on_rpm",),
                f"must be above hybrid_pll_on_rpm {fmt_num(pll_on)} r/min (the hysteresis band)",
                mras_on,
            )
        )
    excite = num(d, "ripple_pll_excite_a")
    if excite is not None and i_max is not None and excite > 0.5 * i_max:
        out.append(
            src.problem(
                ("ripple_pll_excite_a",),
                f"must be at most half of i_max_a {fmt_num(i_max)} A",
                excite,
            )
        )
    if all(x is not None and x > 0 for x in (p, psi, l_d, l_q, i_max, t_max)) and isinstance(
        p, int
    ):
        t_mtpa = mtpa_torque_nm(i_max, p, psi, l_d, l_q)
        if t_max > t_mtpa * 1.001:
            out.append(
                src.problem(
                    ("torque_max_nm",),
                    f"is more than the {t_mtpa:.4g} N m that i_max_a {fmt_num(i_max)} A "
                    f"gives on the MTPA trajectory",
                    t_max,
                )
            )
    return out


_NOT_MOTOR = "is %s, not a motor file"


def _load_motor_source(src: Source) -> tuple[Motor | None, list[Problem]]:
    if src.problems:
        return None, list(src.problems)
    if isinstance(src.data, dict) and "segments" in src.data and "pole_pairs" not in src.data:
        # a profile (or a sweep file) given where a motor file is asked for: say so, not the
        # thirty keys a motor file has and it has not
        return None, [
            Problem(src.path, None, None, None, _NOT_MOTOR % "a profile (it has segments)")
        ]
    if isinstance(src.data, dict) and "effects" in src.data and "pole_pairs" not in src.data:
        return None, [
            Problem(src.path, None, None, None, _NOT_MOTOR % "a rig file (it has effects)")
        ]
    problems: list[Problem] = list(src.soft)
    motor = None
    try:
        motor = Motor.model_validate(src.data)
    except ValidationError as e:
        problems += validation_problems(e, src, Motor)
    problems += motor_checks(src)
    if problems or motor is None:
        return None, problems
    motor._path, motor._yaml_text = src.path, src.text
    if motor.flux_map:
        from .fluxmap import FluxMapError

        try:
            motor.load_flux_map()
        except (OSError, FluxMapError) as e:
            return None, [
                src.problem(
                    ("flux_map",), f"names a flux map that cannot be used: {e}", motor.flux_map
                )
            ]
    return motor, []


def load_motor(path: str | os.PathLike | None = None) -> Motor:
    """Load and validate one motor file (None: the shipped profiles/motors/paper-a-ipmsm.yaml);
    raises ProfileError."""
    path = default_file("motors/paper-a-ipmsm.yaml") if path is None else os.fspath(path)
    motor, problems = _load_motor_source(read_source(path, what="motor file"))
    if motor is None:
        raise ProfileError(problems)
    return motor


class NominalMachine:
    """A motor's attributes with the nominal machine values of a commissioned file (the plant the
    emulator runs is that machine, not what commissioning measured)."""

    def __init__(self, motor: Motor, nominal: dict[str, Any]) -> None:
        self._motor, self._nominal = motor, nominal

    def __getattr__(self, name: str) -> Any:
        if name in self._nominal:
            return self._nominal[name]
        return getattr(self._motor, name)


def nominal_machine(motor: Any) -> Any:
    comm = getattr(motor, "commissioning", None)
    nominal = comm.get("nominal") if isinstance(comm, dict) else None
    return NominalMachine(motor, nominal) if isinstance(nominal, dict) else motor
