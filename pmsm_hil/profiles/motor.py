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

__all__ = [
    "TELEMETRY_RANGE",
    "TELEMETRY_SPEED_MAX_RPM",
    "CurrentSensors",
    "Motor",
    "load_motor",
    "mtpa_currents",
    "mtpa_torque_nm",
]

# The fast telemetry carries speeds, currents and the load as i16 (telem_fast in
# firmware/proto/pmsm_proto.yaml: 0.1 r/min, 2 mA, 1 mN m; tests/test_motor_reach.py checks them
# against it): beyond these the log shows the limit itself. The motor's limits must stay within.
TELEMETRY_SPEED_MAX_RPM = 3276.7
TELEMETRY_RANGE = {
    "speed_max_rpm": (TELEMETRY_SPEED_MAX_RPM, "r/min", "speeds in 0.1 r/min"),
    "i_max_a": (65.534, "A", "currents in 2 mA"),
    "torque_max_nm": (32.767, "N m", "the load in 1 mN m"),
}
# How to get psi_f_wb from a datasheet's back-EMF constant (docs/profiles.md, Motor).
PSI_F_HINT = (
    "psi_f_wb is the peak phase flux linkage, Ke [V/krpm, line-line rms] x sqrt(2/3) / "
    "(104.72 x pole_pairs), or Ke [V/krpm, line-line peak] / (sqrt 3 x 104.72 x pole_pairs); "
    "pole_pairs is half the poles"
)


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

    def voltage_needed_v(self, speed_rpm: float, load_nm: float, mtpa: bool = True) -> float:
        """|u| (peak phase, amplitude-invariant dq) in steady state at ``speed_rpm`` while the
        motor drives ``load_nm`` plus its nominal friction, on the MTPA trajectory (``mtpa``
        False: i_d = 0), from u_d = R i_d - w L_q i_q, u_q = R i_q + w (L_d i_d + psi_f)."""
        w_m = speed_rpm * math.pi / 30.0
        torque = load_nm + self.b_visc_nms * w_m + math.copysign(self.t_coulomb_nm, w_m)
        k_t = self.k_t_nm_per_a
        i_d, i_q = 0.0, abs(torque) / k_t
        if mtpa and abs(torque) > 0:
            lo, hi = 0.0, abs(torque) / k_t  # MTPA torque per ampere is at least k_t
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if self.torque_mtpa_nm(mid) < abs(torque) else (lo, mid)
            i_d, i_q = self.mtpa_currents(hi)
        i_q = math.copysign(i_q, torque)
        w_e = self.pole_pairs * w_m
        u_d = self.r_s_ohm * i_d - w_e * self.l_q_h * i_q
        u_q = self.r_s_ohm * i_q + w_e * (self.l_d_h * i_d + self.psi_f_wb)
        return math.hypot(u_d, u_q)

    @property
    def k_t_nm_per_a(self) -> float:
        """k_t = 1.5 p psi_f (N·m/A), the surface-magnet part; MTPA adds reluctance torque on top."""
        return 1.5 * self.pole_pairs * self.psi_f_wb

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
    for key, (top, unit, how) in TELEMETRY_RANGE.items():
        value = num(d, key)
        if value is not None and value > top:
            out.append(
                src.problem(
                    (key,),
                    f"is beyond the {fmt_num(top)} {unit} that the telemetry carries ({how} on "
                    f"16 bits): the log would show {fmt_num(top)} and the run summary judge "
                    f"that; write {fmt_num(top)} or less",
                    value,
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
    if all(x is not None and x > 0 for x in (p, psi, s_max, v)) and isinstance(p, int):
        out += _back_emf_problems(src, p, psi, s_max, v)
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
    if_i = num(d, "if_start_current_a")
    if if_i is not None and i_max is not None and if_i > i_max:
        out.append(
            src.problem(
                ("if_start_current_a",),
                f"is beyond i_max_a {fmt_num(i_max)} A (the firmware refuses an I/f start "
                "above the current limit)",
                if_i,
            )
        )
    handover = num(d, "if_handover_rpm")
    if handover is not None and s_max is not None and handover > s_max:
        out.append(
            src.problem(
                ("if_handover_rpm",),
                f"is beyond speed_max_rpm {fmt_num(s_max)} r/min (the firmware refuses it)",
                handover,
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
                    f"gives on the MTPA trajectory: write {t_mtpa:.4g} or less, or check "
                    f"psi_f_wb (Wb), l_d_h and l_q_h (H), i_max_a (peak A: a datasheet's rms "
                    f"x sqrt 2)",
                    t_max,
                )
            )
    return out


def _back_emf_problems(
    src: Source, pole_pairs: int, psi_f_wb: float, speed_max_rpm: float, v_dc_v: float
) -> list[Problem]:
    """speed_max_rpm must be reachable without load: the back-EMF psi_f w_e within the linear
    modulation limit v_dc / sqrt 3 (the firmware does not weaken the field)."""
    w_e = pole_pairs * speed_max_rpm * math.pi / 30.0
    emf_v, reach_v = psi_f_wb * w_e, v_dc_v / math.sqrt(3.0)
    if emf_v <= reach_v * 1.001:
        return []
    reach_rpm = reach_v / (pole_pairs * psi_f_wb) * 30.0 / math.pi
    return [
        src.problem(
            ("speed_max_rpm",),
            f"needs a back-EMF of {emf_v:.4g} V peak phase (psi_f_wb {fmt_num(psi_f_wb)} "
            f"Wb x pole_pairs {pole_pairs} x {speed_max_rpm * math.pi / 30.0:.4g} rad/s) but v_dc_v "
            f"{fmt_num(v_dc_v)} V gives at most {reach_v:.4g} V (v_dc_v / sqrt 3; the firmware "
            f"does not weaken the field): write {math.floor(reach_rpm):d} r/min or less, or "
            f"check the motor constants ({PSI_F_HINT})",
            speed_max_rpm,
        )
    ]


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
