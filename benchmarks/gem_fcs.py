"""Speed of gym-electric-motor's finite-control-set PMSM environment, the reference point for our emulator.

gym-electric-motor (GEM, Paderborn University) is the usual open simulator for learning and testing
motor controllers. Its "Finite-CC-PMSM-v0" environment is the nearest thing to our emulator: a PMSM
fed by a two-level B6 bridge whose action is one of the 8 switch states, held for one control period
tau. We configure it with paper A's IPMSM (p 4, R 0.9 ohm, Ld 5 mH, Lq 12 mH, psi_f 0.18 Wb,
J 0.0036 kg m^2) on a 540 V DC link at tau = 50 us, and time env.step() alone: set-up, warm-up,
resets after a constraint violation and the action choice are excluded. The real-time factor is
steps_per_s * tau (simulated seconds per wall-clock second).

Configurations measured (both with GEM's visualisation off, its fastest set-up):
- "default": the environment's own defaults otherwise, i.e. scipy's dopri5 ODE solver (GEM's default
  for this environment) and a constant-speed load (1000 r/min here);
- "euler": GEM's explicit Euler solver with one step per tau (its fastest, least accurate solver).
Our emulator integrates with RK4 and full mechanics, so "default" is the like-for-like figure.

Usage: python benchmarks/gem_fcs.py [sim_seconds]     (needs: pip install gym-electric-motor)
"""

from __future__ import annotations

import math
import sys
import time
from typing import Any

PAPER_A_MOTOR = dict(p=4, r_s=0.9, l_d=5e-3, l_q=12e-3, psi_p=0.18, j_rotor=0.0036)
U_DC_V = 540.0
SPEED_RPM = 1000.0
ENV_ID = "Finite-CC-PMSM-v0"


def _make_env(tau: float, solver: str):
    import gym_electric_motor as gem
    from gym_electric_motor import physical_systems as ps

    omega = SPEED_RPM * math.pi / 30.0
    motor = ps.PermanentMagnetSynchronousMotor(
        motor_parameter=dict(PAPER_A_MOTOR),
        # generous limits so that a random switching sequence rarely trips the current constraint
        limit_values=dict(i=400.0, u=U_DC_V, omega=4000.0 * math.pi / 30.0, torque=100.0),
        nominal_values=dict(i=30.0, u=U_DC_V, omega=1500.0 * math.pi / 30.0, torque=20.0),
    )
    kwargs: dict[str, Any] = dict(
        tau=tau,
        motor=motor,
        supply=dict(u_nominal=U_DC_V),
        load=ps.ConstantSpeedLoad(omega_fixed=omega),
        visualization=(),  # no dashboard: GEM at its fastest
    )
    if solver == "euler":
        kwargs["ode_solver"] = ps.EulerSolver()
    elif solver != "default":
        raise ValueError(f"unknown solver {solver!r}: use 'default' or 'euler'")
    return gem.make(ENV_ID, **kwargs)


def gem_realtime_factor(
    sim_seconds: float = 1.0,
    tau: float = 50e-6,
    *,
    solver: str = "default",
    action: str = "random",
    seed: int = 0,
    repeats: int = 3,
) -> dict:
    """Time GEM's Finite-CC-PMSM env.step() over sim_seconds of simulated time at control period tau.

    action: "random" (uniform over the 8 switch states, drawn before timing) or "fixed" (the zero
    vector). The run is repeated `repeats` times and the fastest is reported (the machine may be
    shared; the median is returned too). Returns env id, GEM version, steps, wall time of the steps,
    steps_per_s and realtime_factor = steps_per_s * tau.
    """
    import random
    import statistics
    import warnings

    warnings.filterwarnings(
        "ignore", module="gymnasium"
    )  # obs-space notes from the passive checker

    import gym_electric_motor as gem

    try:
        from importlib.metadata import version

        gem_version = version("gym-electric-motor")
    except Exception:  # pragma: no cover - metadata missing
        gem_version = getattr(gem, "__version__", "unknown")

    n = max(1, round(sim_seconds / tau))
    env = _make_env(tau, solver)
    rng = random.Random(seed)
    actions = [rng.randrange(8) for _ in range(n)] if action == "random" else [0] * n
    env.reset(seed=seed)
    for a in actions[:200]:  # warm-up (first calls allocate)
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()

    clock = time.perf_counter
    times = []
    resets = 0
    for _ in range(max(1, repeats)):
        env.reset(seed=seed)
        step_time = 0.0
        k = 0
        while k < n:
            t0 = clock()
            # time a run of steps up to the next termination, so the clock is read rarely
            while k < n:
                _, _, terminated, truncated, _ = env.step(actions[k])
                k += 1
                if terminated or truncated:
                    break
            step_time += clock() - t0
            if k < n and (terminated or truncated):
                env.reset()
                resets += 1
        times.append(step_time)
    env.close()
    step_time = min(times)
    steps_per_s = n / step_time
    return {
        "env_id": ENV_ID,
        "gem_version": gem_version,
        "solver": "scipy dopri5 (GEM default)"
        if solver == "default"
        else "GEM EulerSolver, 1 step per tau",
        "load": f"ConstantSpeedLoad {SPEED_RPM:.0f} r/min",
        "motor": dict(PAPER_A_MOTOR, u_dc=U_DC_V),
        "action": action,
        "tau_s": tau,
        "steps": n,
        "resets": resets,
        "wall_s": step_time,
        "repeats": len(times),
        "steps_per_s": steps_per_s,
        "steps_per_s_median": n / statistics.median(times),
        "realtime_factor": steps_per_s * tau,
        "ns_per_step": 1e9 / steps_per_s,
    }


def main(argv: list[str]) -> int:
    sim_seconds = float(argv[1]) if len(argv) > 1 else 1.0
    for solver in ("default", "euler"):
        r = gem_realtime_factor(sim_seconds=sim_seconds, solver=solver)
        print(
            f"{r['env_id']} (gym-electric-motor {r['gem_version']}), {r['solver']}, {r['load']}, "
            f"tau {r['tau_s'] * 1e6:.0f} us, {r['action']} actions: {r['steps']} steps in {r['wall_s']:.2f} s "
            f"-> {r['steps_per_s']:.0f} steps/s, {r['ns_per_step'] / 1e3:.1f} us/step, "
            f"real-time factor {r['realtime_factor']:.3f} (best of {r['repeats']}; median "
            f"{r['steps_per_s_median']:.0f} steps/s; {r['resets']} resets excluded)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
