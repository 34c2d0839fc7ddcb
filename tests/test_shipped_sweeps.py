"""The shipped sweep files (sweeps/): each one loads and plans, and an installed (non-editable)
pmsm-hil finds them by name from any directory, as it finds the shipped profiles."""

from __future__ import annotations

import csv
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import pmsm_hil
from pmsm_hil.profiles import ProfileError
from pmsm_hil.profiles.shipped import resolve, shipped, sweeps_root
from pmsm_hil.sweep import load_sweep, plan_runs


def test_every_shipped_sweep_loads_and_plans():
    files = shipped("sweep")
    assert {p.stem for p in files} >= {"tolerance"}
    for p in files:
        sweep = load_sweep(p)
        assert plan_runs(sweep), p


def test_a_bare_name_finds_the_shipped_sweep():
    assert Path(resolve("tolerance", "sweep")) == sweeps_root() / "tolerance.yaml"
    with pytest.raises(ProfileError) as e:
        resolve("no-such-sweep", "sweep")
    assert "no-such-sweep" in str(e.value) and "tolerance" in str(e.value)


def test_an_installed_pmsm_hil_runs_a_shipped_sweep_by_name_from_any_directory(
    tmp_path, root, built_package
):
    """The package as setup.py installs it (build_py: the Python files and the package data, the
    compiled extension copied beside them), imported from that copy only, in a folder without
    sweeps/ or profiles/."""
    lib = built_package
    assert (lib / "pmsm_hil" / "shipped" / "sweeps" / "tolerance.yaml").is_file()
    assert (lib / "pmsm_hil" / "shipped" / "paper-a-identify.yaml").is_file()
    for so in Path(pmsm_hil.__file__).parent.glob("_fw*.so"):
        shutil.copy(so, lib / "pmsm_hil" / so.name)
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": str(lib)}
    where = subprocess.run(
        [
            sys.executable,
            "-c",
            "from pmsm_hil.profiles.shipped import resolve; print(resolve('tolerance', 'sweep'))",
        ],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
    )
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()).is_relative_to(lib)
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pmsm_hil.cli.main",
            "sweep",
            "tolerance",
            "--out",
            "X",
            "--limit",
            "1",
            "--workers",
            "1",
            "--no-progress",
        ],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    with open(work / "X" / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1 and rows[0]["status"] == "ok", rows
    assert "rig_effects_sensor_gain_i_b_gain" in rows[0]
