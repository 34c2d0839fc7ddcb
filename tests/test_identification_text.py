"""The identification table as `run` and `analyze` print it: paper A's Table 2 beside it only for
paper A's motor, and estimates that never moved named with the guard that held them."""

from __future__ import annotations

from pmsm_hil.analysis.identification import PARAMS, Cell, IdentTable, text_table

TRUTH = {"l_d_h": 0.00065, "l_q_h": 0.00065, "psi_f_wb": 0.016568, "r_s_ohm": 0.19}


def _table(motor: str) -> IdentTable:
    table = IdentTable("x.mcap", "/sim/truth", 0.0, 3.0, motor=motor)
    for est in ("rls", "nlms_adaline"):
        for p in PARAMS:
            frozen = p == "l_d_h"
            final = 0.0 if frozen else TRUTH[p]
            err = final - TRUTH[p]
            table.cells.append(
                Cell(
                    est,
                    p,
                    final,
                    TRUTH[p],
                    err,
                    err / TRUTH[p],
                    None if frozen else 2.0,
                    None if frozen else 0.05,
                    False,
                    0.01,
                )
            )
    return table


def test_paper_a_table_only_beside_paper_a_motor():
    assert "paper A's Table 2" not in text_table(_table("lv400"))
    assert "paper A's Table 2" in text_table(_table("paper-a-ipmsm"))
    assert "paper A's Table 2" in text_table(_table("paper-a-ipmsm-commissioned"))
    assert "paper A's Table 2" in text_table(_table(""))  # no motor metadata: as before
    assert "paper A's Table 2" in text_table(_table("lv400"), with_paper=True)  # bench identify


def test_never_updated_estimates_are_named_with_their_guard():
    text = text_table(_table("lv400"))
    (line,) = [ln for ln in text.splitlines() if ln.startswith("never updated")]
    assert "rls L_d; nlms_adaline L_d." in line
    assert "inject_a" in line and "docs/identification.md" in line


def test_an_estimate_run_to_zero_after_updating_is_named_as_diverged():
    table = _table("lv400")
    table.cells.append(Cell("adaline", "l_q_h", 0.0, 0.00065, -0.00065, -1.0, 0.4, None, False))
    text = text_table(table)
    (line,) = [ln for ln in text.splitlines() if ln.startswith("at 0 after updating")]
    assert "adaline L_q." in line and "L_d" not in line.split(".")[0]  # never updated: not here
    assert "NLMS-Adaline normalises its step" in line
    assert not any(ln.startswith("at 0") for ln in text_table(_table("lv400")).splitlines())


def test_the_table_fits_an_80_column_terminal():
    # run and analyze print it after the run: rows wider than 80 columns wrap every line there
    text = text_table(_table("paper-a-ipmsm"))
    rows = [ln for ln in text.splitlines() if ln.startswith("  ") and "paper: " not in ln]
    assert len(rows) == 2 * 5  # a header and four parameters per estimator
    assert max(len(ln) for ln in rows) <= 80
    assert all("|" in ln for ln in rows)  # paper A's columns beside ours
