"""The firmware build's identity (fwlib.source_id: a hash of the C sources the emulator was compiled
from) in the journals' keys: a sweep or a batch of trials resumed after a firmware change runs
again instead of taking the old build's results, and a worker with another build refuses the
work with both builds named (docs/sweep.md)."""

from __future__ import annotations

import os
import runpy
from pathlib import Path

import setuptools

from pmsm_hil.emulator import fwlib
from pmsm_hil.sweep import load_sweep, run_sweep
from pmsm_hil.sweep.plan import run_key
from pmsm_hil.sweep.tasks import run_tasks, task_key

ROOT = Path(__file__).resolve().parents[1]
OTHER = "0123456789abcdef"  # a build that is not this one


def _count(task):
    Path(task["calls"], f"{task['x']}-{os.getpid()}-{len(os.listdir(task['calls']))}").touch()
    return {"x": task["x"]}


def test_the_loaded_extension_is_the_build_of_these_sources(monkeypatch):
    """setup.py's hash of the sources now equals the one compiled into the extension: a C file
    changed without rebuilding is caught here."""
    monkeypatch.chdir(ROOT)
    monkeypatch.setattr(setuptools, "setup", lambda **kw: None)
    ns = runpy.run_path(str(ROOT / "setup.py"), run_name="pmsm_hil_setup")
    assert len(fwlib.source_id()) == 16
    assert ns["source_sha256"]() == fwlib.source_id()


def test_keys_carry_the_firmware_build(monkeypatch):
    task = {"x": 1}
    texts = {"profile.yaml": "a", "motor.yaml": "b", "rig.yaml": "c"}
    here = task_key(task), run_key(texts, 1)
    assert (task_key(task), run_key(texts, 1)) == here  # the same inputs, the same keys
    monkeypatch.setattr(fwlib, "source_id", lambda: OTHER)
    other = task_key(task), run_key(texts, 1)
    assert other[0] != here[0] and other[1] != here[1]


def test_trials_of_another_build_are_not_taken_from_the_journal_and_its_workers_refuse(
    tmp_path, monkeypatch
):
    calls = tmp_path / "calls"
    calls.mkdir()
    tasks = [{"x": x, "calls": str(calls)} for x in (1, 2)]
    first = run_tasks(_count, tasks, tmp_path / "out", name="c", workers=1, progress=False)
    assert first == [{"x": 1}, {"x": 2}] and len(os.listdir(calls)) == 2
    own = fwlib.source_id()
    # the client now has another build than its workers (as after `pip install` of a changed tree
    # on the client only): the journal's results are not this build's, and the workers refuse
    monkeypatch.setattr(fwlib, "source_id", lambda: OTHER)
    again = run_tasks(_count, tasks, tmp_path / "out", name="c", workers=1, progress=False)
    assert len(os.listdir(calls)) == 2  # nothing ran on the wrong build
    for r in again:
        assert r["error"] == (
            f"this worker's firmware build is {own}, the client's {OTHER}: install the same "
            "pmsm-hil on every worker"
        )


def test_a_sweep_on_workers_of_another_build_fails_its_runs_with_both_builds(tmp_path, monkeypatch):
    data = ROOT / "tests" / "data"
    p = tmp_path / "s.yaml"
    p.write_text(
        f"name: t\nprofile: {data / 'short.yaml'}\naxes:\n  - {{field: seed, values: [3]}}\n"
    )
    monkeypatch.setattr(fwlib, "source_id", lambda: OTHER)
    res = run_sweep(load_sweep(p), tmp_path / "out", workers=1, progress=False)
    assert res.failed == 1 and res.ok == 0
    assert f"the client's {OTHER}" in res.rows[0]["error"]
