"""The sections of a profile file as written (control, telemetry, link, segments) and the limits
they are checked against; `profile.py` turns them into a validated `Profile`."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, PrivateAttr

from ..protocol import generated as gen
from ._base import StrictModel
from .acceptance import Acceptance

# the speed loop's crossover when a profile leaves its gains null (pmsm_hil.control_design designs
# them; docs/control.md, "Speed loop")
DEFAULT_SPEED_BW_RAD_S = 450.0

TS_MIN_S = 20e-6
TS_MAX_S = 1e-3
MAX_TOTAL_DURATION_S = 3600.0
MAX_SEGMENTS = (
    64  # PROFILE_MAX_SEGMENTS, the firmware's profile table (firmware/core/profile_exec.h)
)

# Serial link budget. Payload octets per frame as in firmware/proto/pmsm_proto.yaml (the test
# suite checks these against it); each frame adds id, seq, CRC-16 (2), the COBS code octet and
# the 0x00 delimiter.
FRAME_OVERHEAD_OCTETS = 6
# the streamed messages' payloads, from the protocol's one source (the generated module)
PAYLOAD_OCTETS = {
    n: gen.BY_NAME[n].length for n in ("telem_fast", "params", "status", "sim_truth", "telem_est")
}
OCTETS_PER_SYMBOL = 10  # UART 8N1: start + 8 data + stop bits

# ----------------------------------------------------------------------------------- models


class PredictorScale(StrictModel):
    l_d_h: float = Field(1.0, gt=0, le=100, description="factor on the motor file's l_d_h")
    l_q_h: float = Field(1.0, gt=0, le=100, description="factor on l_q_h")
    psi_f_wb: float = Field(1.0, ge=0, le=100, description="factor on psi_f_wb")
    r_s_ohm: float = Field(1.0, ge=0, le=100, description="factor on r_s_ohm")


class EstimatorSettings(StrictModel):
    bw_rad_s: float | None = Field(
        None, gt=0, le=1e4, description="tracking (adaptation) bandwidth, rad/s (null: 300)"
    )
    min_speed_rpm: float | None = Field(
        None,
        ge=0,
        le=1e5,
        description="below this speed the estimator is not locked (null: 5 % of the motor's "
        "rated speed for mras)",
    )
    lock_timeout_s: float = Field(
        0.05,
        ge=0,
        le=10,
        description="the lost_lock fault trips after the estimator closing the loop has been "
        "out of lock this long, s",
    )
    theta0_rad: float = Field(
        0.0, ge=-7, le=7, description="the estimator's initial electrical angle, rad"
    )


class Control(StrictModel):
    ts_s: float = Field(50e-6, ge=TS_MIN_S, le=TS_MAX_S, description="control (MPCC) period, s")
    rho: float = Field(1.0, gt=0, le=1000, description="MPCC cost weight of the q-axis error")
    current_ref: Literal["mtpa", "id_zero"] = Field(
        "mtpa", description="d-axis current reference rule"
    )
    current_ctrl: Literal["mpcc", "foc"] = Field(
        "mpcc",
        description="current controller: mpcc (finite-control-set, paper A) or foc (dq PI "
        "loops with SVPWM, paper B; docs/sensorless.md)",
    )
    mpcc_candidates: Literal["all", "adjacent"] = Field(
        "all",
        description="MPCC candidate set: all 8 switching states, or paper A Table 1's three "
        "single-leg flips of the applied state (two adjacent active vectors and a zero vector)",
    )
    foc_bw_rad_s: float | None = Field(
        None, gt=0, le=1e5, description="FOC current-loop bandwidth, rad/s (null: 2 pi / (20 ts_s))"
    )
    angle_src: Literal["encoder", "mras", "ripple_pll", "hybrid"] = Field(
        "encoder",
        description="what gives the control its angle and speed: the encoder, or a sensorless "
        "estimator (docs/sensorless.md); the encoder stays in the log as truth",
    )
    estimator: EstimatorSettings = Field(
        default_factory=EstimatorSettings,
        description="settings of the angle estimator (control.angle_src other than encoder)",
    )
    speed_kp_a_per_rad_s: float | None = Field(
        None,
        gt=0,
        le=1e4,
        description="speed PI proportional gain, A per mechanical rad/s (null: designed)",
    )
    speed_ki_a_per_rad: float | None = Field(
        None,
        ge=0,
        le=1e7,
        description="speed PI integral gain, A per mechanical rad (null: designed)",
    )
    speed_obs_bw_rad_s: float | None = Field(
        None,
        gt=0,
        le=1e5,
        description="encoder speed observer bandwidth, rad/s (null: the host's default)",
    )
    speed_loop_hz: float = Field(1000.0, gt=0, le=50_000, description="speed loop rate, Hz")
    heartbeat_timeout_s: float = Field(
        0.5,
        ge=0.05,
        le=10,
        description="stop when the host is silent, s (the firmware refuses more than 10 s)",
    )
    dead_time_comp: bool = Field(True, description="firmware compensates the inverter dead time")
    identify: bool = Field(
        False,
        description="run the three online estimators (RLS, Adaline, "
        "NLMS-Adaline) and send their params frames",
    )
    predictor: Literal["nominal", "rls", "adaline", "nlms_adaline"] = Field(
        "nominal",
        description="what feeds the MPCC predictor: the motor file (times predictor_scale) "
        "or an estimator once it has converged",
    )
    predictor_scale: PredictorScale = Field(
        default_factory=PredictorScale,
        description="mismatch factors on the motor file's values in the predictor",
    )
    id_window_s: float = Field(
        1e-3,
        ge=2 * TS_MIN_S,
        le=0.1,
        description="estimator update period: window over which u, i, w are averaged, s",
    )


class PlantStep(StrictModel):
    r_s_scale: float = Field(
        1.0, gt=0, lt=10, description="true R = motor value x this, from the segment start"
    )
    psi_f_scale: float = Field(1.0, gt=0, lt=10, description="true psi_f = motor value x this")


class Telemetry(StrictModel):
    fast_hz: float = Field(
        2000.0, ge=0, le=50_000, description="telem_fast frame rate, Hz (0: off)"
    )
    params_hz: float = Field(
        100.0, ge=0, le=50_000, description="params frames per estimator, Hz (0: off)"
    )
    status_hz: float = Field(10.0, gt=0, le=50_000, description="status frame rate, Hz")
    truth_hz: float = Field(
        100.0, ge=0, le=50_000, description="sim_truth frame rate (emulator), Hz (0: off)"
    )
    est_hz: float = Field(
        250.0,
        ge=0,
        le=50_000,
        description="telem_est frame rate, Hz (0: off; sent only when control.angle_src is an "
        "estimator)",
    )


Control.model_rebuild()


class CanLinkSettings(StrictModel):
    """CAN link settings (docs/can.md); a rate left null is the `telemetry` section's."""

    bitrate: int = Field(1_000_000, ge=10_000, le=1_000_000, description="CAN bit rate, bit/s")
    node: int = Field(1, ge=0, le=15, description="CAN node ID of the drive")
    fast_hz: float | None = Field(None, ge=0, le=50_000, description="telem_fast rate on CAN, Hz")
    params_hz: float | None = Field(None, ge=0, le=50_000, description="params rate on CAN, Hz")
    status_hz: float | None = Field(None, gt=0, le=50_000, description="status rate on CAN, Hz")
    truth_hz: float | None = Field(None, ge=0, le=50_000, description="sim_truth rate on CAN, Hz")
    est_hz: float | None = Field(None, ge=0, le=50_000, description="telem_est rate on CAN, Hz")


class Link(StrictModel):
    baud: int = Field(921_600, ge=9_600, le=20_000_000, description="serial bit rate, bit/s")
    can: CanLinkSettings = Field(
        default_factory=CanLinkSettings, description="CAN link (docs/can.md)"
    )


class Segment(StrictModel):
    name: str | None = Field(None, description="label shown in the live view and the events")
    duration_s: float = Field(gt=0, le=MAX_TOTAL_DURATION_S, description="length of the segment, s")
    speed_rpm: float = Field(description="speed reference (target), r/min")
    ramp_rpm_s: float = Field(
        0.0, ge=0, le=1e6, description="ramp rate towards speed_rpm, r/min/s (0: step)"
    )
    load_nm: float = Field(0.0, description="load torque during the segment, N m")
    capture: bool = Field(False, description="trigger a control-rate capture at the segment start")
    estimate: bool = Field(
        True,
        description="the online estimators update in this segment (false holds "
        "them, e.g. while spinning up)",
    )
    kind: Literal["run", "identify_r", "commission"] = Field(
        "run",
        description="run: speed/load as given; identify_r: R by d-axis current injection at "
        "standstill (speed_rpm must be 0); commission: the firmware's commissioning sequence "
        "(docs/commissioning.md; `pmsm-hil commission`), the duration its time limit",
    )
    inject_a: float = Field(
        0.0,
        ge=-1000,
        le=1000,
        description="identify_r: d current (first half; half of it in the second half); "
        "run: amplitude of a square-wave i_d excitation, A",
    )
    inject_hz: float = Field(
        10.0, ge=0, le=1000, description="run: frequency of the i_d excitation, Hz"
    )
    plant: PlantStep | None = Field(
        None, description="emulator only: step the plant's true R and psi_f at the segment start"
    )
    angle_encoder: bool = Field(
        False,
        description="close the loop on the encoder in this segment while the sensorless "
        "estimator runs beside it (e.g. a start-up below the estimator's speed range)",
    )

    current_ctrl: Literal["mpcc", "foc"] | None = Field(
        None,
        description="current controller from this segment on (null: the previous segment's, "
        "or control.current_ctrl for the first); handed over bumplessly at the segment start "
        "(docs/control.md)",
    )

    _index: int = PrivateAttr(default=0)
    _t_start_s: float = PrivateAttr(default=0.0)
    _speed_start_rpm: float = PrivateAttr(default=0.0)

    @property
    def index(self) -> int:
        return self._index

    @property
    def t_start_s(self) -> float:
        return self._t_start_s

    @property
    def t_end_s(self) -> float:
        return self._t_start_s + self.duration_s

    @property
    def speed_start_rpm(self) -> float:
        """Speed reference at the segment start (where the previous segment left it)."""
        return self._speed_start_rpm

    @property
    def speed_end_rpm(self) -> float:
        """Speed reference at the segment end (short of speed_rpm if the ramp is too slow)."""
        if self.ramp_rpm_s <= 0.0:
            return self.speed_rpm
        gap = self.speed_rpm - self._speed_start_rpm
        reach = self.ramp_rpm_s * self.duration_s
        return (
            self.speed_rpm
            if abs(gap) <= reach
            else self._speed_start_rpm + math.copysign(reach, gap)
        )

    @property
    def flags(self) -> int:
        """profile_segment.flags on the wire (enum segment_flag of the protocol)."""
        bits = gen.ENUMS["segment_flag"]
        return (
            (bits["capture"] if self.capture else 0)
            | (0 if self.estimate else bits["hold_est"])
            | (bits["angle_encoder"] if self.angle_encoder else 0)
            | (bits["cc_foc"] if self.current_ctrl == "foc" else 0)
            | (bits["cc_mpcc"] if self.current_ctrl == "mpcc" else 0)
        )

    @property
    def label(self) -> str:
        return self.name if self.name else f"segment {self._index}"


class ProfileFile(StrictModel):
    """The profile file as written."""

    name: str = Field(min_length=1, description="profile name")
    description: str = Field("", description="text")
    motor: str = Field(min_length=1, description="motor file, relative to the profile file")
    rig: str | None = Field(
        None,
        description="rig file, relative to the profile file "
        "(null: rigs/default.yaml beside the motors directory)",
    )
    control: Control = Field(default_factory=Control)
    telemetry: Telemetry = Field(default_factory=Telemetry)
    link: Link = Field(default_factory=Link)
    segments: list[Segment] = Field(
        min_length=1, max_length=MAX_SEGMENTS, description="list of segments played in order"
    )
    acceptance: Acceptance | None = Field(
        None, description="bounds a run must meet for `pmsm-hil test` (nothing on the device)"
    )
