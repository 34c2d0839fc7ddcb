"""Sweeps: one profile over grids and random draws of profile fields, motor parameters, rig effect
magnitudes and seeds, run in process on Dask workers, one row of metrics per run (docs/sweep.md).

    from pmsm_hil.sweep import load_sweep, plan_runs, run_sweep
    sweep = load_sweep("sweeps/tolerance.yaml")
    outcome = run_sweep(sweep, Path("sweep-out"), limit=8)
"""

from .driver import SweepOutcome, run_sweep, write_inputs
from .execute import execute_run, run_in_process
from .plan import Run, plan_runs
from .results import Journal, read_table, write_table
from .spec import METRICS, Sweep, load_sweep

__all__ = [
    "METRICS",
    "Journal",
    "Run",
    "Sweep",
    "SweepOutcome",
    "execute_run",
    "load_sweep",
    "plan_runs",
    "read_table",
    "run_in_process",
    "run_sweep",
    "write_inputs",
    "write_table",
]
