"""What a sweep and `pmsm-hil test` leave in a CI log and a results folder: progress lines
without a terminal, and a results table whose columns do not move when a sweep is resumed."""

from __future__ import annotations

import re

from pmsm_hil.sweep import write_table
from pmsm_hil.sweep.driver import PLAIN_EVERY_S, _Bar
from pmsm_hil.sweep.results import Journal


def test_without_a_terminal_progress_is_a_plain_line_as_runs_finish(capsys):
    """Before, rich printed its bar once, at the end: a sweep in CI (stdout a file) said nothing
    between its first line and its last, however long it ran."""
    assert PLAIN_EVERY_S == 5.0
    with _Bar(12, 2, enabled=True, missed=0) as bar:  # 2 done before (a resumed sweep)
        bar.advance(True, 1.0, met=True)
        assert capsys.readouterr().out == (
            "sweep: 3/12 runs done, 0 failed to run, 0 missed the criteria; "
            "60.0 runs/min, about 0:00:09 left\n"
        )
        for t in range(2, 10):  # a run a second: a line at most every 5 s
            bar.advance(t != 4, float(t), met=t != 6)
        assert capsys.readouterr().out == (
            "sweep: 8/12 runs done, 1 failed to run, 1 missed the criteria; "
            "60.0 runs/min, about 0:00:04 left\n"
        )
    # interrupted with 11 of 12 done: where it stopped, said once more
    out = capsys.readouterr().out
    assert out.startswith("sweep: 11/12 runs done, 1 failed to run, 1 missed the criteria; ")
    with _Bar(2, 0, enabled=True, label="test") as bar:
        bar.advance(True, 3.0)
        bar.advance(True, 4.0)  # the last: always said, without a time left
    lines = capsys.readouterr().out.splitlines()
    assert lines == [
        "test: 1/2 runs done, 0 failed to run; 20.0 runs/min, about 0:00:03 left",
        "test: 2/2 runs done, 0 failed to run; 30.0 runs/min",
    ]
    assert not re.search(r"[\x00-\x08\x0b-\x1f\x7f]", "\n".join(lines))
    with _Bar(2, 0, enabled=False) as bar:  # --no-progress: nothing
        bar.advance(True, 3.0)
    assert capsys.readouterr().out == ""


def _header(out) -> list[str]:
    return (out / "results.csv").read_text().splitlines()[0].replace('"', "").split(",")


def test_a_resumed_sweeps_table_has_the_columns_where_a_fresh_one_has_them(tmp_path):
    """Before, the journal's rows were written with their keys sorted: after a resume (the rows
    read back from OUT/results.jsonl) results.csv had its metric columns in alphabetical order
    (acceptance_failed, complete, faults, id_..., seg0_...), a fresh sweep's in the metrics'
    order (seg0_speed_error_rpm, ..., faults, complete)."""
    row = {
        "index": 0,
        "key": "k0",
        "status": "ok",
        "seed": 1,
        "seg0_speed_error_rpm": 0.1,
        "speed_error_max_rpm": 0.1,
        "faults": 0,
        "complete": True,
        "acceptance_failed": 0,
        "state": "done",
        "wall_s": 1.5,
    }
    fresh, resumed = tmp_path / "fresh", tmp_path / "resumed"
    fresh.mkdir()
    resumed.mkdir()
    write_table(fresh, [row], ["seed"])
    Journal(resumed).add(row)
    write_table(resumed, list(Journal(resumed).rows.values()), ["seed"])
    assert _header(resumed) == _header(fresh)
    assert _header(fresh)[4:8] == [
        "seg0_speed_error_rpm",
        "speed_error_max_rpm",
        "faults",
        "complete",
    ]


def test_the_test_table_keeps_each_check_on_one_line_without_a_terminal(capsys, monkeypatch):
    """Before, `pmsm-hil test` in a CI log (no terminal, no COLUMNS: 120 columns) wrapped a row
    whose names were long onto two lines ("segment 3 'drift R +30 %, psi_f" / "-5 %'"), so that
    `grep FAIL` found half of the scope and not the criterion's last word."""
    from pmsm_hil.cli.test import _print
    from pmsm_hil.sweep.suite import SuiteCase

    monkeypatch.delenv("COLUMNS", raising=False)
    scope = "segment 3 'drift R +30 %, psi_f -5 %'"
    checks = [
        {
            "scope": scope,
            "criterion": "nlms_adaline psi_f_wb convergence",
            "measured": "0.030 s",
            "bound": "<= 0.5 s",
            "passed": True,
        },
        {
            "scope": scope,
            "criterion": "speed error",
            "measured": "+12.345 r/min",
            "bound": "|.| <= 10 r/min (band)",
            "passed": False,
        },
    ]
    _print([SuiteCase(profile="my-drive.yaml", name="my-drive", status="ok", checks=checks)])
    lines = capsys.readouterr().out.splitlines()
    fail = [line for line in lines if "FAIL" in line and scope in line]
    assert len(fail) == 1 and "speed error" in fail[0] and "+12.345 r/min" in fail[0]
    assert any(scope in line and "nlms_adaline psi_f_wb convergence" in line for line in lines)
    assert not any(line.strip() in ("-5 %'", "convergence") for line in lines)
