"""Emulator speed: device time per wall time, at Ts = 50 us, for the firmware core + sim board.

Runs paper A's profile on the emulated device in this process (no host decoding: the octets the
UART sends are produced and dropped), and, in the same run, gym-electric-motor's finite-control-set
PMSM environment on the same motor and inverter (benchmarks/gem_fcs.py). Prints both as multiples
of real time and their ratio.

    python3 benchmarks/emulator_speed.py [--profile profiles/paper-a.yaml] [--rig FILE] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # idle BLAS threads spin on the second core
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pmsm_hil.emulator.settings import emulator_settings  # noqa: E402
from pmsm_hil.profiles import load_profile  # noqa: E402
from pmsm_hil.protocol.session import Session  # noqa: E402
from pmsm_hil.runner import configure  # noqa: E402
from pmsm_hil.transport.inproc import InProcessTransport  # noqa: E402


def start_inproc(profile, seed: int = 1):
    """The emulator in this process, configured for ``profile`` and started: (device, session)."""
    settings = emulator_settings(
        profile.motor, profile.rig, seed=seed, baud=profile.link.baud, ts_s=profile.control.ts_s
    )
    tr = InProcessTransport(settings)
    s = Session(tr)
    s.hello()
    configure(s, profile)
    s.request("start")
    return tr.dev, s


def emulator_realtime_factor(profile_path: str, rig: str | None = None, seed: int = 1) -> dict:
    profile = load_profile(profile_path, rig_override=rig)
    dev, s = start_inproc(profile, seed)
    ticks = 0
    octets = 0
    t0 = time.perf_counter()
    c0 = time.process_time()
    while dev.active:
        n, out = dev.run(4000)  # 0.2 s: within the heartbeat timeout
        ticks += n
        octets += len(out)
        # keep the heartbeat alive the way the host would (no decoding)
        s.send("heartbeat", counter=ticks)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    device_s = ticks * profile.control.ts_s
    return {
        "device_s": device_s,
        "wall_s": wall,
        "ticks": ticks,
        "octets": octets,
        "ns_per_period": wall / ticks * 1e9,
        "realtime_factor": device_s / wall,
        "cpu_s": cpu,  # this process's CPU time: less moved by other jobs on a shared machine
        "cpu_realtime_factor": device_s / cpu if cpu > 0 else float("inf"),
        "rig": rig or str(getattr(profile.rig, "path", "default")),
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--profile", default=str(ROOT / "profiles" / "paper-a.yaml"))
    ap.add_argument(
        "--rig",
        action="append",
        default=None,
        help="rig file(s) to measure (default: the profile's rig)",
    )
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument(
        "--gem-seconds",
        type=float,
        default=0.5,
        help="simulated seconds of gym-electric-motor per repeat",
    )
    ap.add_argument("--no-gem", action="store_true")
    args = ap.parse_args()

    rigs = args.rig or [None]
    gem = None
    if not args.no_gem:
        try:
            sys.path.insert(0, str(ROOT / "benchmarks"))
            from gem_fcs import gem_realtime_factor as gem
        except ImportError as e:
            print(f"gym-electric-motor not measured: {e} (pip install gym-electric-motor)")
    # interleaved repeats: ours and GEM's measured under the same machine load
    ours: dict = {rig: [] for rig in rigs}
    gems: list = []
    for _ in range(args.repeat):
        for rig in rigs:
            ours[rig].append(emulator_realtime_factor(args.profile, rig))
        if gem is not None:
            gems.append(gem(sim_seconds=args.gem_seconds, tau=50e-6, repeats=1))
    for _rig, runs in ours.items():
        best = max(runs, key=lambda r: r["realtime_factor"])
        med = sorted(r["realtime_factor"] for r in runs)[len(runs) // 2]
        name = Path(best["rig"]).name
        print(
            f"pmsm-hil emulator, rig {name}: {best['device_s']:.2f} s of device time; best "
            f"{best['realtime_factor']:.0f}x real time ({best['ns_per_period']:.0f} ns per "
            f"{1e6 * 50e-6:.0f} us period), median {med:.0f}x, over {len(runs)} runs"
        )
    if not gems:
        return
    gbest = max(g["realtime_factor"] for g in gems)
    gmed = sorted(g["realtime_factor"] for g in gems)[len(gems) // 2]
    print(
        f"gym-electric-motor {gems[0].get('env_id', '')} {gems[0].get('version', '')}: best "
        f"{gbest:.2f}x real time, median {gmed:.2f}x, over {len(gems)} runs"
    )
    for _rig, runs in ours.items():
        ratios = sorted(
            r["realtime_factor"] / g["realtime_factor"] for r, g in zip(runs, gems, strict=False)
        )
        print(
            f"ratio pmsm-hil/gym-electric-motor, rig {Path(runs[0]['rig']).name}: median "
            f"{ratios[len(ratios) // 2]:.0f}x (per-run pairs; range {ratios[0]:.0f}-{ratios[-1]:.0f}x)"
        )


if __name__ == "__main__":
    main()
