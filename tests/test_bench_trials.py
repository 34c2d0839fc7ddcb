"""The benchmarks' rigs-and-seeds runs as trials on the sweep's Dask machinery
(pmsm_hil.bench.trials): `bench sensorless`, `bench commission` and `bench identify --rigs` give
on a two-worker cluster the tables of their runs made one by one in this process, and a second
call with the same output folder runs nothing again."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from pmsm_hil.bench import commission, identify_rigs
from pmsm_hil.bench import identify as bench
from pmsm_hil.bench.trials import BenchInputError, Cluster, parse_seeds
from pmsm_hil.cli.main import main as cli_main

DATA = Path(__file__).parent / "data"


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


@pytest.mark.parametrize(
    ("text", "seeds"),
    [("1-10", list(range(1, 11))), ("1,2,5", [1, 2, 5]), (" 3 , 0-1 ", [3, 0, 1]), ("7,", [7])],
)
def test_seeds_are_numbers_ranges_and_lists_of_them(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("1-0", "the range 1-0 is empty (give the lower seed first, e.g. 0-1)"),
        ("a-b", "'a-b' is not a seed or a range of seeds (whole numbers 0..2147483647"),
        ("-1", "'-1' is not a seed"),
        ("2147483648", "'2147483648' is not a seed"),
        ("", "no seeds given"),
        (" , ", "no seeds given"),
        ("1-3,2", "seed 2 is given twice"),
        ("1-100000", "more than 10000 seeds"),
    ],
)
def test_seeds_that_are_no_list_of_seeds_are_refused_saying_why(text, why):
    with pytest.raises(BenchInputError) as e:
        parse_seeds(text)
    assert why in str(e.value)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["commission", "--rigs", "default", "--seeds", "1-0"], "--seeds 1-0: the range 1-0 is"),
        (["identify", "--rigs", "default", "--seeds", "3-1"], "--seeds 3-1: the range 3-1 is"),
        (["sensorless", "--seeds", "a-b"], "--seeds a-b: 'a-b' is not a seed"),
        (["commission", "--seeds", "1,1"], "--seeds 1,1: seed 1 is given twice"),
        (["commission", "--rigs", ","], "--rigs ,: no rigs given"),
        (["commission", "--rigs", "nosuch", "--seeds", "1"], "nosuch: is neither a file nor a "),
        (["identify", "--seeds", "1-3"], "--seeds 1-3: only with --rigs or --per-effect --commis"),
        (
            ["identify", "--profile", "paper-a"],
            "--profile paper-a: profile paper-a does not identify (its control.identify is false)",
        ),
        (
            ["sensorless", "--only", "paper-b-start", "--seeds", "11", "--rigs", "default"],
            "--only paper-b-start: no scenario's profile or name contains 'paper-b-start'; the "
            "scenarios, by profile: paper-b: 'paper B: speed step",
        ),
    ],
)
def test_bad_bench_input_is_one_error_line_before_anything_runs(argv, message, tmp_path, capsys):
    """Exit 2 with the option and its value named, nothing run and no output folder made."""
    out = tmp_path / "out"
    assert cli_main(["bench", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in " ".join(err.split()), err
    assert "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--commissioned"], "--commissioned: only with --rigs or --per-effect"),
        (["--rigs", "default", "--mismatch"], "--mismatch: not with --rigs"),
        (["--rigs", "default", "--rig", "lab-typical"], "--rig: not with --rigs"),
        (["--rigs", "default", "--until", "2"], "--until: not with --rigs"),
        (["--rigs", "default", "--seed", "3"], "--seed: not with --rigs"),
        (["--rigs", "default", "--only", "mismatch"], "--only: not with --rigs"),
        (["--per-effect", "--commissioned", "--rigs", "default"], "--rigs: not with --per-effect"),
        (["--per-effect", "--commissioned", "--motor", "paper-a-ipmsm"], "--motor: not with --per"),
        (["--only", "mismatch", "--motor", "paper-a-ipmsm"], "--motor: not with --only mismatch"),
    ],
)
def test_bench_identify_refuses_an_option_it_would_not_use(argv, message, tmp_path, capsys):
    """An option that the chosen part of `bench identify` does not use is refused before anything
    runs, not ignored: `--commissioned` alone had run the nominal motor, `--rigs ... --mismatch`
    had left the mismatch out, both with exit 0."""
    out = tmp_path / "out"
    assert cli_main(["bench", "identify", *argv, "--out", str(out)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert err.startswith("error: ") and message in err, err
    assert not out.exists()


def test_the_sensorless_refusal_lists_every_scenario(capsys, tmp_path):
    from pmsm_hil.bench.sensorless import SCENARIOS

    assert cli_main(["bench", "sensorless", "--only", "nosuch", "--out", str(tmp_path / "o")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert all(repr(sc.name) in err for sc in SCENARIOS)


def test_bench_help_names_the_defaults(capsys, monkeypatch):
    """Every option of `bench identify` and `bench commission` says what it is and its default;
    the default profile by its shipped name, not a path in the repository."""
    monkeypatch.setenv("COLUMNS", "300")  # argparse wraps at the terminal's width: no hyphen split
    with pytest.raises(SystemExit):
        cli_main(["bench", "identify", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: the shipped paper-a-identify)" in text
    assert "profiles/paper-a-identify.yaml" not in text
    assert "--seed N emulator noise seed" in text
    with pytest.raises(SystemExit):
        cli_main(["bench", "commission", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "default default,lab-typical" in text and "seeds (default 1-10)" in text


def test_bench_help_says_what_each_benchmark_runs_and_where_it_writes(capsys, monkeypatch):
    """`bench identify|commission|sensorless --help` open with what the benchmark runs (how long,
    how to make it smaller) and name the default output folder: before, only the options."""
    monkeypatch.setenv("COLUMNS", "300")
    for which, says, out in (
        (
            "identify",
            "Runs an identification profile (paper-a-identify, or --profile) on the emulator (a few seconds)",
            "runs/bench-identify",
        ),
        ("commission", "Commissions the emulated drive on every rig and seed", None),
        ("sensorless", "--only paper-b --rigs default --seeds 11", "runs/bench-sensorless"),
    ):
        with pytest.raises(SystemExit):
            cli_main(["bench", which, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert says in text, which
        if out:
            assert f"default {out})" in text, which


def test_bench_commission_takes_the_users_motor(tmp_path, capsys):
    """`bench commission --motor` commissions the user's own motor on the user's rig (a 48 V rig
    would not suit paper A's 540 V motor) and scores each step against that plant."""
    motor, rig = DATA / "servo-48v.yaml", DATA / "servo-48v-rig.yaml"
    out = tmp_path / "out"
    args = ["bench", "commission", "--motor", str(motor), "--rigs", str(rig), "--seeds", "1"]
    assert cli_main([*args, "-o", str(out)]) == 0
    md = (out / "commission.md").read_text()
    assert "motor servo-48v" in md
    assert "1 of 1 seeds completed" in md
    rows = [line for line in md.splitlines() if line.startswith("| ") and "/1 |" in line]
    assert len(rows) >= 9, md
    assert all(line.endswith("1/1 |") for line in rows), md


def test_an_interrupted_bench_says_where_its_trials_are_kept(tmp_path, monkeypatch, capsys):
    """A Ctrl-C after the trials (while the tables are written) said only "interrupted": the
    line now says that the trials done are kept in --out and that the same command takes them
    up (the trials' own phase says how many were done, pmsm_hil.sweep.tasks)."""

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(commission, "bench_commission", interrupted)
    out = tmp_path / "bc"
    code = cli_main(["bench", "commission", "--rigs", "default", "--seeds", "1", "--out", str(out)])
    assert code == 130
    err = " ".join(capsys.readouterr().err.split())
    assert f"pmsm-hil bench: interrupted; the trials done are kept in {out}" in err, err
    assert "the same command takes them up" in err and "Traceback" not in err
