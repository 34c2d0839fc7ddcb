"""The gap diagnosis's fit pool (pmsm_hil.gap.pool): results in the jobs' order whatever order they
run and end in, the same fits in a worker as in this process, BLAS on one thread."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_info

from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.pool import FitJob, FitPool, one_blas_thread
from pmsm_hil.gap.probe import Probe
from pmsm_hil.gap.record import load_record
from pmsm_hil.profiles import load_motor

ROOT = Path(__file__).resolve().parents[1]
MOTOR = ROOT / "profiles/motors/paper-a-ipmsm.yaml"


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    from pmsm_hil.gapgen.recorder import record_profile

    tmp = tmp_path_factory.mktemp("gappool")
    rig = tmp / "dt.yaml"
    rig.write_text(
        "name: dt\ndescription: test\nv_dc_v: null\neffects:\n"
        "  dead_time: {dead_time_s: 1.5e-6, v_drop_v: 1.0, i_dt_a: 0.5}\n"
    )
    out = tmp / "dt.mcap"
    record_profile(ROOT / "tests/data/gap-short.yaml", out, rig_path=rig, seed=5, full_log=False)
    return Probe(load_record(out), MotorModel.from_motor(load_motor(MOTOR)))


def _jobs(probe):
    sel = np.arange(0, len(probe.idx), 3)
    test = np.arange(1, len(probe.idx), 3)
    return [
        FitJob(("dead_time",), sel, 24, test=test),
        FitJob(("encoder",), sel, 12),
        FitJob(("sensor_gain",), sel, 24, test=test),
    ]


def test_a_worker_fits_as_this_process_does_in_the_jobs_order(probe):
    jobs = _jobs(probe)
    with FitPool(probe, workers=1) as here:
        alone = here.map(jobs)
    ended: list[int] = []
    with FitPool(probe, workers=2) as pool:
        # started longest-first by the given cost (the last job first): still returned in order
        side = pool.map(jobs, done=lambda j, n: ended.append(j), cost=[1.0, 2.0, 3.0])
        assert len(pool.seconds) == 3 and all(s > 0 for s in pool.seconds)
    assert sorted(ended) == [0, 1, 2]
    for (fa, ra), (fb, rb), job in zip(alone, side, jobs, strict=True):
        assert fa.names == fb.names == job.names
        for n in job.names:
            assert np.array_equal(fa.x[n], fb.x[n]) and np.array_equal(fa.se[n], fb.se[n])
        assert fa.cost == fb.cost
        assert (ra is None) == (rb is None) == (job.test is None)
        if ra is not None:
            assert np.array_equal(ra, rb) and ra.shape == (len(job.test), 2)
    # the dead time the record carries is what the first job found
    assert alone[0][0].x["dead_time"][0] == pytest.approx(1.5e-6, rel=0.3)


def test_a_job_submitted_alone_and_blas_on_one_thread(probe):
    job = _jobs(probe)[1]
    with FitPool(probe, workers=2) as pool:
        later = pool.submit(job)
        f, r = later.result()
    with FitPool(probe) as here:
        f1, _ = here.submit(job).result()
    assert r is None and np.array_equal(f.x["encoder"], f1.x["encoder"])
    with one_blas_thread():
        blas = [i for i in threadpool_info() if i["user_api"] == "blas"]
        assert blas and all(i["num_threads"] == 1 for i in blas)


def test_the_fit_processes_are_born_deaf_to_ctrl_c(probe):
    """Ctrl-C goes to the whole process group: a fit process still importing when it came raised
    KeyboardInterrupt there, with a traceback on the terminal. They are made with SIGINT blocked
    (a child keeps its parent's mask), and this process's mask is as it was."""
    import signal

    before = signal.pthread_sigmask(signal.SIG_BLOCK, set())
    with FitPool(probe, workers=2) as pool:
        kids = [p.pid for p in pool._ex._processes.values()]
        assert len(kids) == 2
        for pid in kids:
            status = Path(f"/proc/{pid}/status").read_text()
            blocked = int(
                next(ln for ln in status.splitlines() if ln.startswith("SigBlk:")).split()[1], 16
            )
            assert blocked & (1 << (signal.SIGINT - 1)), status
        assert signal.pthread_sigmask(signal.SIG_BLOCK, set()) == before


def test_a_fit_process_that_starts_after_its_pool_closed_says_nothing(tmp_path, capsys):
    """Closed by Ctrl-C while a fit process still started, the pool's folder is gone: its
    initializer raised FileNotFoundError and the terminal showed a traceback after "interrupted"."""
    import signal

    from pmsm_hil.gap.pool import _start_worker

    old = signal.getsignal(signal.SIGINT)
    try:
        assert _start_worker(str(tmp_path / "gone" / "probe.pickle")) is None
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, old)
    assert capsys.readouterr().err == ""
