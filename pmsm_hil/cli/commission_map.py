"""`pmsm-hil commission --flux-map`: after the sequence, the flux map measured under load on the
commissioned motor file (pmsm_hil/commission/flux_map.py, docs/commissioning.md)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.cli.errors import fail, report
from pmsm_hil.files import write_text_whole

if TYPE_CHECKING:
    from pmsm_hil.device import DeviceSpec
    from pmsm_hil.profiles import Profile
    from pmsm_hil.recorder import LiveState


class MapPrinter:
    """One line per operating point as the run reaches it."""

    def __init__(self, n_segments: int):
        self.n_events = 0
        self.n_segments = n_segments

    def message(self, text: str) -> None:
        print(text, flush=True)

    def update(self, live: LiveState) -> None:
        for t_s, kind, arg, _text in live.events[self.n_events :]:
            if kind == "segment_start":
                print(f"{t_s:7.2f} s  flux map: segment {arg + 1} of {self.n_segments}", flush=True)
        self.n_events = len(live.events)


def measure_map(
    motor_out: Path,
    commission: Profile,
    spec: DeviceSpec,
    log: Path,
    device: str,
    speeds_rpm: list[float] | None,
) -> int:
    """Run the flux-map profile on `motor_out` (the commissioned file, rewritten with the map);
    0 on success, else the exit code after the message."""
    import numpy as np

    from pmsm_hil.commission.flux_map import (
        csv_text,
        errors_against,
        flux_map_profile,
        measure,
        plan_for,
        truth_map,
    )
    from pmsm_hil.commission.motor_file import with_flux_map
    from pmsm_hil.device import open_device
    from pmsm_hil.errors import TransportError
    from pmsm_hil.log.reader import read_log
    from pmsm_hil.profiles import ProfileError
    from pmsm_hil.protocol.session import DeviceError, Session
    from pmsm_hil.runner import HostError, RunOptions, run_profile

    try:
        plan = plan_for(commission.motor, speeds_rpm)
        profile = flux_map_profile(motor_out, commission.rig.path, plan, commission.control.ts_s)
    except (ValueError, ProfileError) as e:
        return fail("error", f"--flux-map: {e}", 2)
    log_map = log.with_name(log.stem + "-flux-map.mcap")
    lo, hi = plan.speeds_rpm
    print(
        f"flux map: {plan.n_points} operating points at {lo:g} and {hi:g} r/min under FOC "
        f"({profile.total_duration_s:.1f} s)",
        flush=True,
    )
    try:
        link = open_device(spec, profile)
    except TransportError as e:
        return fail("error", str(e), 3)
    printer = MapPrinter(len(profile.segments))
    try:
        run = run_profile(
            profile,
            Session(link),
            log_map,
            RunOptions(
                seed=None if spec.is_rig else spec.seed,
                capture=False,
                log_sync="batch" if spec.is_rig else "wall",
            ),
            printer,
        )
    except (DeviceError, TransportError, HostError) as e:
        return fail("error", f"flux map: {e} (log: {log_map})", 3)
    finally:
        link.close()
    print(f"log: {log_map}")
    if run.interrupted:
        report("stopped", f"flux map interrupted; the motor was stopped (log: {log_map})")
        return 130
    if run.state != "done" or run.faults or run.error:
        why = run.error or run.stop_reason or run.state
        return fail("failed", f"flux map did not complete: {why} (log: {log_map})", 4)
    mlog = read_log(log_map)
    points = measure(mlog, plan, profile.motor, profile.control.ts_s)
    if len(points) < plan.n_points:
        return fail(
            "failed",
            f"flux map: {len(points)} of {plan.n_points} operating points measured (log: {log_map})",
            4,
        )
    csv_path = motor_out.with_name(motor_out.stem + "-flux-map.csv")
    write_text_whole(csv_path, csv_text(points, device))
    record = {
        "file": csv_path.name,
        "log": str(log_map),
        "speeds_rpm": [float(lo), float(hi)],
        "points": len(points),
    }
    write_text_whole(motor_out, with_flux_map(motor_out.read_text(), csv_path.name, record))
    print(f"flux map: {csv_path} ({len(points)} points)")
    if not spec.is_rig:  # the emulator knows the truth: say how close the map came
        tr = mlog.topic("/sim/truth")
        psi_f, l_d, l_q = (float(np.mean(tr[k])) for k in ("psi_f_wb", "l_d_h", "l_q_h"))
        lin = (psi_f, l_d, l_q)
        err = errors_against(points, truth_map(profile), lin)
        print(
            f"flux map against the emulator's plant: psi_d {1e3 * err['psi_d_rms_wb']:.2f} mWb rms "
            f"({1e3 * err['psi_d_max_wb']:.2f} worst), psi_q {1e3 * err['psi_q_rms_wb']:.2f} mWb "
            f"rms ({1e3 * err['psi_q_max_wb']:.2f} worst)"
        )
    return 0
