"""The benchmarks' rigs-and-seeds runs as trials on the sweep's Dask machinery
(pmsm_hil.bench.trials): `bench sensorless`, `bench commission` and `bench identify --rigs` give
on a two-worker cluster the tables of their runs made one by one in this process, and a second
call with the same output folder runs nothing again."""

from __future__ import annotations

import subprocess
import sys

import pytest

from pmsm_hil.bench import commission, identify_rigs
from pmsm_hil.bench import identify as bench
from pmsm_hil.bench.trials import Cluster


def _quiet(*_a):
    return None


def _here(monkeypatch, module):
    """Make ``module``'s trials run one by one in this process (the reference)."""
    monkeypatch.setattr(
        module, "run_trials", lambda fn, tasks, out, cluster=None, **kw: [fn(t) for t in tasks]
    )


def _stamps(folder):
    return {p.name: p.stat().st_mtime_ns for p in sorted(folder.glob("*.mcap"))}


def test_bench_sensorless_on_dask_gives_the_table_of_runs_made_here(tmp_path, monkeypatch):
    from pmsm_hil.bench.sensorless_report import sensorless

    kw = {"seeds": (11, 12), "rigs": ("default",), "only": "paper-b", "echo": _quiet}
    res = sensorless(tmp_path / "dask", cluster=Cluster(workers=2), **kw)
    logs = _stamps(tmp_path / "dask")
    assert len(logs) == 2 and (tmp_path / "dask" / "bench.jsonl").is_file()
    again = sensorless(tmp_path / "dask", cluster=Cluster(workers=1), **kw)
    assert _stamps(tmp_path / "dask") == logs  # from the journal: no run made again
    assert again == res
    monkeypatch.setattr(
        bench, "run_jobs", lambda jobs, out, cluster=None: [bench.bench_run(j) for j in jobs]
    )
    here = sensorless(tmp_path / "here", **kw)
    assert here.keys() == res.keys() and here == res
    md = (tmp_path / "dask" / "sensorless.md").read_text()
    assert md == (tmp_path / "here" / "sensorless.md").read_text()
    assert "paper-b" in md or "paper B" in md


def test_bench_commission_on_dask_gives_the_table_of_runs_made_here(tmp_path, monkeypatch):
    dask = commission.bench_commission(
        ["default"], [1, 2], tmp_path / "dask", echo=_quiet, cluster=Cluster(workers=2)
    )
    assert "2 of 2 seeds completed" in dask
    _here(monkeypatch, commission)
    here = commission.bench_commission(["default"], [1, 2], tmp_path / "here", echo=_quiet)
    assert here == dask


def test_bench_identify_rigs_on_dask_gives_the_table_of_runs_made_here(tmp_path, monkeypatch):
    path = bench.default_profile()
    dask = identify_rigs.identify_rigs(
        path, ["default"], [1, 2], tmp_path / "dask", echo=_quiet, cluster=Cluster(workers=2)
    )
    assert "2 of 2 seeds ran" in dask
    logs = _stamps(tmp_path / "dask")
    assert len(logs) == 2
    identify_rigs.identify_rigs(
        path, ["default"], [1, 2], tmp_path / "dask", echo=_quiet, cluster=Cluster(workers=1)
    )
    assert _stamps(tmp_path / "dask") == logs
    _here(monkeypatch, identify_rigs)
    here = identify_rigs.identify_rigs(path, ["default"], [1, 2], tmp_path / "here", echo=_quiet)
    assert here == dask


def test_a_trial_that_raises_is_a_failed_seed_of_the_table(tmp_path):
    """A rig file the worker cannot load is a seed that did not complete, with the reason, not
    the end of the benchmark."""
    rig = tmp_path / "broken.yaml"
    rig.write_text("name: broken\nno_such_field: 1\n")
    text = commission.bench_commission(
        [str(rig)], [1, 2], tmp_path / "out", echo=_quiet, cluster=Cluster(workers=1)
    )
    assert "0 of 2 seeds completed" in text
    assert text.count("no_such_field") == 2, text


@pytest.mark.parametrize("bad", ["0", "-2", "two"])
def test_workers_must_be_a_positive_number(bad):
    r = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", "bench", "sensorless", "--workers", bad],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    assert f"--workers: {bad!r}: give a whole number of workers, at least 1" in r.stderr
