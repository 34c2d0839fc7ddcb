"""The augmentation library: one low-parameter model per unmodelled effect, named as the rig effects
are (docs/rigs.md), written from the physics of the drive and not from the emulator's code
(docs/gap.md, "Which"). Each augmentation acts on one stage of the probe:

- ``meas``: what the sensors report (sensor_offset, sensor_gain, encoder; the current-sample part
  of delay),
- ``volt``: the voltage the inverter really applies (dead_time; the PWM-update part of delay),
- ``plant``: the machine (thermal, saturation, iron_loss, flux_harmonics).

``dc_link`` (the measured v_dc already enters the probe: its ripple is shown, not fitted) and the
mechanical effects (``friction``, ``cogging``: the torque balance) are assessed by their own views
in ``pmsm_hil.gap.views``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pmsm_hil.gap.model import MotorModel

ALPHA_R_PER_K = 0.00393  # copper
ALPHA_PSI_PER_K = -0.001  # NdFeB


@dataclass
class Work:
    """The probe's inputs as an augmented model sees them (full-length arrays)."""

    i_abc: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    cmd: np.ndarray | None  # switch states / duties (N, 3), None for u_alpha_beta data
    kind: str
    v_dc: np.ndarray
    pwm_on: np.ndarray
    first: np.ndarray  # True at the first sample of a run
    u_ab: np.ndarray | None = None  # set by the voltage stage
    leg_dist_v: np.ndarray | None = None  # (N, 3) pole-voltage distortion
    r_scale: float = 1.0
    psi_scale: float = 1.0
    sat: tuple | None = None
    g_fe_s: float = 0.0
    harm: tuple | None = None  # (a5, a7) complex
    sample_frac: float = 0.0
    pwm_delay: float = 0.0
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Effect:
    name: str
    stage: str
    params: tuple[str, ...]
    x0: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    apply: Callable[[Work, np.ndarray, object], None]
    report: Callable[[np.ndarray, MotorModel], dict[str, float]]  # rig-file parameters from x
    primary: str  # the rig parameter quoted as "magnitude"
    needs: str = ""  # "switch": only with switch-state/duty data
    starts: tuple[tuple[float, ...], ...] = ()  # further start points for the fit


def current_sign(i_abc: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The smooth sign of the phase currents that the dead-time model (parameters x) uses."""
    return np.tanh(i_abc / max(x[2], 1e-3))


def _dead_time(w: Work, x, m) -> None:
    w.extra["dead_time"] = np.asarray(x, float)


def dead_time_dist(
    x: np.ndarray,
    kind: str,
    cmd: np.ndarray,
    prev: np.ndarray,
    i_abc: np.ndarray,
    v_dc: np.ndarray,
    pwm_on: np.ndarray,
    was_off: np.ndarray,
    ts_s: float,
    sg: np.ndarray | None = None,
) -> np.ndarray:
    """Pole-voltage distortion (M, 3) of the inverter over a period (dead time and device drop).
    ``sg``: current_sign(i_abc, x) if already computed."""
    td, v_drop, _ = x
    if sg is None:
        sg = current_sign(i_abc, x)
    if kind == "switch":
        d = cmd - prev
        d[was_off] = 0.0
        rise, fall = (d > 0.5).astype(float), (d < -0.5).astype(float)
        k_dt = (v_dc * td / ts_s)[:, None]
        # a rising edge comes t_d late when the current keeps the lower diode on (i > 0), a falling
        # edge when it keeps the upper one on (i < 0); the device drop opposes the current
        dist = -v_drop * sg - k_dt * (rise * 0.5 * (1 + sg) - fall * 0.5 * (1 - sg))
    else:
        dist = -((v_dc * td / ts_s)[:, None] + v_drop) * sg
    dist[~pwm_on] = 0.0
    return dist


def _delay(w: Work, x, m) -> None:
    w.sample_frac = float(x[0]) / m.ts_s
    w.pwm_delay = float(x[1])


def _encoder(w: Work, x, m) -> None:
    w.theta = w.theta - x[0]


def _offset(w: Work, x, m) -> None:
    w.i_abc = w.i_abc - np.array([x[0], x[1], 0.0])


def _gain(w: Work, x, m) -> None:
    w.i_abc = w.i_abc / np.array([1.0, x[0], 1.0])


def _thermal(w: Work, x, m) -> None:
    w.r_scale *= 1 + ALPHA_R_PER_K * x[0]
    w.psi_scale *= 1 + ALPHA_PSI_PER_K * x[1]


def _saturation(w: Work, x, m) -> None:
    w.sat = tuple(float(v) for v in x)


def _iron(w: Work, x, m) -> None:
    w.g_fe_s = float(x[0]) * 1e-3


def _harm(w: Work, x, m) -> None:
    w.harm = (complex(x[0], x[1]), complex(x[2], x[3]))


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "dead_time",
            "volt",
            ("dead_time_s", "v_drop_v", "i_dt_a"),
            (1e-6, 0.5, 0.5),
            (0.0, 0.0, 0.05),
            (2e-5, 10.0, 5.0),
            _dead_time,
            lambda x, m: {
                "dead_time_s": float(x[0]),
                "v_drop_v": float(x[1]),
                "i_dt_a": float(x[2]),
            },
            "dead_time_s",
            needs="switch",
        ),
        Effect(
            "delay",
            "volt",
            ("sample_delay_s", "pwm_delay_periods"),
            (5e-6, 0.0),
            (0.0, 0.0),
            (4e-5, 3.0),
            _delay,
            lambda x, m: {"sample_delay_s": float(x[0]), "pwm_delay_periods": float(x[1])},
            "total_delay_s",
            starts=((5e-6, 1.0), (5e-6, 2.0)),
        ),
        Effect(
            "encoder",
            "meas",
            ("offset_e_rad",),
            (0.0,),
            (-0.5,),
            (0.5,),
            _encoder,
            lambda x, m: {"offset_e_rad": float(x[0])},
            "offset_e_rad",
        ),
        Effect(
            "sensor_offset",
            "meas",
            ("i_a_a", "i_b_a"),
            (0.0, 0.0),
            (-2.0, -2.0),
            (2.0, 2.0),
            _offset,
            lambda x, m: {"i_a_a": float(x[0]), "i_b_a": float(x[1]), "i_c_a": 0.0},
            "offset_norm_a",
        ),
        Effect(
            "sensor_gain",
            "meas",
            ("i_b_gain",),
            (1.0,),
            (0.8,),
            (1.25,),
            _gain,
            lambda x, m: {"i_a_gain": 1.0, "i_b_gain": float(x[0]), "i_c_gain": 1.0},
            "i_b_gain",
        ),
        Effect(
            "thermal",
            "plant",
            ("d_temp_winding_k", "d_temp_magnet_k"),
            (0.0, 0.0),
            (-80.0, -150.0),
            (200.0, 200.0),
            _thermal,
            lambda x, m: {
                "temp_winding_c": 25.0 + float(x[0]),
                "temp_magnet_c": 25.0 + float(x[1]),
                "temp_ref_c": 25.0,
                "alpha_r_per_k": ALPHA_R_PER_K,
                "alpha_psi_per_k": ALPHA_PSI_PER_K,
            },
            "d_temp_winding_k",
        ),
        Effect(
            "saturation",
            "plant",
            ("k_d", "i_sd_a", "k_q", "i_sq_a", "k_x", "k_c"),
            (0.05, 5.0, 0.05, 5.0, 0.0, 0.0),
            (-0.9, 2.0, -0.9, 2.0, -3.0, -3.0),
            (0.9, 50.0, 0.9, 50.0, 3.0, 3.0),
            _saturation,
            lambda x, m: {
                "k_d": float(x[0]),
                "i_sd_a": float(x[1]),
                "k_q": float(x[2]),
                "i_sq_a": float(x[3]),
                "k_x": float(x[4]),
                "k_c": float(x[5]),
            },
            "k_q",
            starts=((0.3, 3.0, 0.3, 3.0, 0.0, 0.0),),
        ),
        Effect(
            "iron_loss",
            "plant",
            ("g_fe_ms",),
            (1.0,),
            (0.0,),
            (100.0,),
            _iron,
            lambda x, m: {"r_fe_ohm": 1e3 / max(float(x[0]), 1e-9)},
            "r_fe_ohm",
        ),
        Effect(
            "flux_harmonics",
            "plant",
            ("a5_re", "a5_im", "a7_re", "a7_im"),
            (0.0,) * 4,
            (-0.3,) * 4,
            (0.3,) * 4,
            _harm,
            lambda x, m: {
                "emf5_rel": float(abs(complex(x[0], x[1]))),
                "emf7_rel": float(abs(complex(x[2], x[3]))),
            },
            "emf5_rel",
        ),
    )
}


def _params(w: Work, x, m) -> None:
    w.r_scale *= x[0]
    w.extra["l_scale"] = (float(x[1]), float(x[2]))
    w.psi_scale *= x[3]


# The parametric gap: best constant R, Ld, Lq, psi_f (scales of the nominal values); not a rig effect.
PARAMETERS = Effect(
    "parameters",
    "plant",
    ("r_scale", "ld_scale", "lq_scale", "psi_scale"),
    (1.0,) * 4,
    (0.3, 0.3, 0.3, 0.3),
    (3.0, 3.0, 3.0, 3.0),
    _params,
    lambda x, m: {
        "r_s_ohm": float(x[0]) * m.r_s_ohm,
        "l_d_h": float(x[1]) * m.l_d_h,
        "l_q_h": float(x[2]) * m.l_q_h,
        "psi_f_wb": float(x[3]) * m.psi_f_wb,
    },
    "r_scale",
)

# Effects the library names but that the current residual does not fit (their own views).
VIEW_EFFECTS = ("dc_link", "friction", "cogging")
ALL_NAMES = tuple(EFFECTS) + VIEW_EFFECTS
STAGE_ORDER = {"meas": 0, "volt": 1, "plant": 2}


def primary_value(eff: Effect, x: np.ndarray, m: MotorModel, ts_s: float = 0.0) -> float:
    """The number quoted as the effect's magnitude (``eff.primary``)."""
    rep = eff.report(x, m)
    if eff.primary == "total_delay_s":  # current-sample delay plus the late PWM update
        return float(x[0] + x[1] * ts_s)
    if eff.primary == "offset_norm_a":
        a, b = rep["i_a_a"], rep["i_b_a"]
        return float(np.hypot(a, (a + 2 * b) / np.sqrt(3.0)))
    if eff.primary in rep:
        return float(rep[eff.primary])
    return float(x[eff.params.index(eff.primary)])
