"""Sweeps: what the end line, the progress bar and `sweep report` say (runs completed against runs
that met the acceptance criteria), the columns of a relative axis (the factor and the value in its
unit), the whole-run maxima against their segments, and an older pmsm-hil's result directory."""

from __future__ import annotations

import json
import math
import re
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest
from cli_helpers import CLI

from pmsm_hil.profiles import ProfileError
from pmsm_hil.sweep import load_sweep, read_table, run_sweep, write_table
from pmsm_hil.sweep.driver import SweepOutcome, _Bar
from pmsm_hil.sweep.metrics import summary_metrics
from pmsm_hil.sweep.report import write_report
from pmsm_hil.sweep.results import ResultsFormatError
from pmsm_hil.sweep.spec import factor_column


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def judged_sweep(tmp_path_factory):
    """tests/data/short.yaml with acceptance criteria, two runs on one worker: a recovery bound
    of 0.1 ms that no load step meets, and one of 1 s that it does; the winding R at 1.1 x the
    motor file's 0.9 ohm."""
    tmp = tmp_path_factory.mktemp("judged")
    data = Path(__file__).parent / "data"
    profile = (
        (data / "short.yaml")
        .read_text()
        .replace("../../profiles/", f"{data.parent.parent}/profiles/")
    )
    (tmp / "short.yaml").write_text(profile + "acceptance:\n  run: {complete: true}\n")
    sweep = tmp / "s.yaml"
    sweep.write_text(
        "name: judged\nprofile: short.yaml\nmetrics: [speed_error, recovery, faults, completeness]\n"
        "axes:\n"
        "  - {field: motor.r_s_ohm, values: [1.1], relative: true}\n"
        "  - {field: profile.acceptance.run.recovery_max_s, values: [1.0e-4, 1.0]}\n"
    )
    out = tmp / "out"
    r = _cli("sweep", str(sweep), "--out", str(out), "--workers", "1", "--no-progress")
    assert r.returncode == 0, r.stderr
    return sweep, out, r.stdout


def test_the_end_line_tells_runs_completed_from_runs_that_met_the_criteria(judged_sweep):
    sweep, out, stdout = judged_sweep
    assert "runs: 2 completed, 0 failed to run, 0 done before" in stdout
    assert (
        f"acceptance criteria: met by 1 of the 2 completed runs, missed by 1 "
        f"(`pmsm-hil sweep report {out}` for the metrics)" in stdout
    )
    assert " ok," not in stdout  # "ok" read as a pass was the confusion
    # resumed: nothing to run, the verdict still counts the runs done before
    r = _cli("sweep", str(sweep), "--out", str(out), "--workers", "1", "--no-progress")
    assert r.returncode == 0, r.stderr
    assert "runs: 0 completed, 0 failed to run, 2 done before" in r.stdout
    assert "acceptance criteria: met by 1 of the 2 completed runs, missed by 1" in r.stdout


def test_end_lines_count_failed_runs_apart_and_say_when_nothing_is_judged(tmp_path):
    rows = [
        {"status": "ok", "complete": True, "faults": 0, "acceptance_failed": 0},
        {"status": "ok", "complete": True, "faults": 0, "acceptance_failed": 2},
        {"status": "failed", "error": "invalid inputs"},
    ]
    res = SweepOutcome(out=tmp_path, planned=3, ok=2, failed=1, rows=rows, criteria=True)
    ran, judged = res.end_lines()
    assert ran.startswith("runs: 2 completed, 1 failed to run, 0 done before")
    assert judged.startswith("acceptance criteria: met by 1 of the 2 completed runs, missed by 1")
    plain = [{k: v for k, v in r.items() if k != "acceptance_failed"} for r in rows]
    res = SweepOutcome(out=tmp_path, planned=3, ok=2, failed=1, rows=plain, criteria=False)
    assert res.end_lines()[1] == (
        "acceptance criteria: none in the profile, nothing judged (2 of the 2 completed runs "
        "played it whole without a fault)"
    )


def test_the_progress_bar_counts_failed_to_run_and_missed_criteria_apart():
    from rich.console import Console

    bar = _Bar(3, 0, enabled=True, label="test", missed=0)
    bar.advance(True, 1.0, met=True)
    bar.advance(True, 2.0, met=False)
    bar.advance(False, 3.0, met=False)  # a run that failed to run missed nothing
    assert (bar.done, bar.failed, bar.missed) == (3, 1, 1)
    console = Console(record=True, width=200)
    console.print(bar.progress.make_tasks_table(bar.progress.tasks))
    text = console.export_text()
    assert text.lstrip().startswith("test")
    assert "3/3" in text and "1 failed to run" in text and "1 missed the criteria" in text
    # without criteria (a sweep of a profile without them, the other trials) no such column
    plain = _Bar(1, 0, enabled=True, label="sweep")
    plain.advance(True, 1.0, met=False)
    console = Console(record=True, width=200)
    console.print(plain.progress.make_tasks_table(plain.progress.tasks))
    assert "missed" not in console.export_text() and plain.missed is None


def test_the_progress_bar_keeps_its_numbers_whole_at_80_columns(monkeypatch):
    """A terminal of 80 columns cannot hold the bar, the counts, the rate and the time left on one
    line: the counts go on a second line (before, rich cut them short: "12…", "0:0…")."""
    monkeypatch.setenv("FORCE_COLOR", "1")  # a terminal, as rich sees it
    monkeypatch.setenv("NO_COLOR", "1")

    def shown(width: int, total: int) -> list[str]:
        monkeypatch.setenv("COLUMNS", str(width))
        bar = _Bar(total, 0, enabled=True, missed=0)
        for i in range(12):
            bar.advance(i != 3, 6.0, met=i % 5 != 0)
        console = bar.progress.console
        assert console.is_terminal and console.width == width
        with console.capture() as cap:
            console.print(*bar.progress.get_renderables())
        return [re.sub(r"\x1b\[[0-9;]*m", "", line) for line in cap.get().splitlines()]

    for total in (40, 1000):
        lines = shown(80, total)
        assert all(len(line) <= 80 and "…" not in line for line in lines), lines
        text = "\n".join(lines)
        assert f"12/{total} runs done" in text and "120.0 runs/min" in text
        assert "1 failed to run, 3 missed the criteria" in text
        assert len(lines) == 2
    assert len(shown(160, 40)) == 1  # room enough: one line, as before


def test_pmsm_hil_test_labels_its_progress_test(monkeypatch, tmp_path):
    from pmsm_hil.profiles.shipped import shipped_file
    from pmsm_hil.sweep import driver
    from pmsm_hil.sweep.suite import plan_suite, run_suite

    seen = {}

    def fake_run_runs(runs, out, metrics, **kw):
        seen.update(kw)
        return SweepOutcome(out=out, planned=len(runs))

    monkeypatch.setattr(driver, "run_runs", fake_run_runs)
    cases = plan_suite([shipped_file("paper-a.yaml"), shipped_file("paper-b.yaml")])
    run_suite(cases, tmp_path, progress=True)
    assert seen["label"] == "test" and seen["progress"] is True


def test_a_relative_axis_has_its_factor_and_its_value_in_ohms(judged_sweep):
    _sweep, out, _ = judged_sweep
    rows = read_table(out)
    for r in rows:
        assert r["motor_r_s_factor"] == 1.1
        assert r["motor_r_s_ohm"] == pytest.approx(0.99)  # 1.1 x the file's 0.9 ohm
        inputs = (out / "runs" / r["key"] / "motor.yaml").read_text()
        assert f"r_s_ohm: {r['motor_r_s_ohm']!r}\n" in inputs
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert header[4:7] == [
        '"motor_r_s_factor"',
        '"motor_r_s_ohm"',
        '"profile_acceptance_run_recovery_max_s"',
    ]
    meta = json.loads((out / "sweep.json").read_text())
    assert meta["format"] == 2
    assert meta["axes"][0]["column"] == "motor_r_s_factor"
    assert meta["axes"][0]["value_column"] == "motor_r_s_ohm"
    # the report plots against the factor and treats neither column as a metric
    write_report(out)
    summary = (out / "report" / "summary.md").read_text()
    assert "| motor_r_s" not in summary and not (out / "report" / "motor_r_s_ohm.png").exists()


@pytest.mark.parametrize(
    "name, column",
    [
        ("motor_r_s_ohm", "motor_r_s_factor"),
        ("motor_psi_f_wb", "motor_psi_f_factor"),
        ("rig_effects_dead_time_dead_time_s", "rig_effects_dead_time_dead_time_factor"),
        ("profile_control_speed_kp_a_per_rad_s", "profile_control_speed_kp_factor"),
        ("rig_effects_thermal_alpha_r_per_k", "rig_effects_thermal_alpha_r_factor"),
        ("rig_effects_sensor_gain_i_b_gain", "rig_effects_sensor_gain_i_b_gain_factor"),
    ],
)
def test_a_factor_column_drops_the_unit(name, column):
    assert factor_column(name) == column


def test_two_axes_with_one_results_column_are_an_error_at_the_line(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(
        "name: t\nprofile: paper-a\naxes:\n"
        "  - {field: rig.effects.x.i_a_a, values: [1.1], relative: true}\n"
        "  - {field: rig.effects.x.i_a_v, values: [1.1], relative: true}\n"
    )
    with pytest.raises(ProfileError) as e:
        load_sweep(p)
    assert (
        f"{p}:5: axes[1].field = 'rig.effects.x.i_a_v' has the results column "
        "'rig_effects_x_i_a_factor' of axes[0] (rig.effects.x.i_a_a)" in str(e.value)
    )


def test_a_whole_run_maximum_is_never_below_one_of_its_segments(judged_sweep):
    seg = SimpleNamespace
    summary = SimpleNamespace(
        segments=[
            # standstill: the rotor creeps during an R injection (tolerance sweep: +0.50 r/min)
            seg(index=0, setpoint_rpm=0.0, mean_error_rpm=-0.5048, ripple_d_a=1.4, ripple_q_a=0.6),
            seg(
                index=1, setpoint_rpm=1000.0, mean_error_rpm=0.1166, ripple_d_a=1.1, ripple_q_a=0.9
            ),
            seg(
                index=2, setpoint_rpm=1000.0, mean_error_rpm=-0.002, ripple_d_a=1.0, ripple_q_a=0.8
            ),
        ],
        faults=[],
        complete=True,
    )
    m = summary_metrics(summary, ["speed_error", "ripple"])
    assert m["speed_error_max_rpm"] == 0.5048
    assert m["speed_error_max_at_speed_rpm"] == 0.1166
    assert (m["ripple_d_max_a"], m["ripple_q_max_a"]) == (1.4, 0.9)
    # and in a sweep's table: no _max below |one of its seg columns|
    _sweep, out, _ = judged_sweep
    for r in read_table(out):
        for k, v in r.items():
            if k.startswith("seg") and k.endswith("_speed_error_rpm") and not math.isnan(v):
                assert r["speed_error_max_rpm"] >= abs(v), (k, v)


def test_sweep_report_prints_the_metrics_and_the_pass_count(judged_sweep):
    _sweep, out, _ = judged_sweep
    r = _cli("sweep", "report", str(out))
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    head = next(ln for ln in lines if "metric" in ln)
    assert head.split() == ["metric", "runs", "median", "worst"]
    row = next(ln for ln in lines if ln.split()[:1] == ["seg1_recovery_s"]).split()
    rows = read_table(out)
    rec = sorted(x["seg1_recovery_s"] for x in rows)
    assert row[1] == "2" and float(row[2]) == pytest.approx(sum(rec) / 2, rel=1e-3)
    assert float(row[3]) == pytest.approx(rec[-1], rel=1e-3)
    assert (
        "2 runs: 2 completed, 0 failed to run; 1 of 2 met the profile's acceptance criteria "
        "(and played the whole profile without a fault), 1 did not"
    ) in " ".join(r.stdout.split())
    assert f"report {out}/report/summary.md and " in r.stdout


def _old_directory(out: Path) -> None:
    """A result directory as pmsm-hil wrote it before format 2: a relative axis's factor under
    the field's name, no "format" in sweep.json."""
    out.mkdir()
    rows = [
        {
            "index": i,
            "key": f"k{i}",
            "status": "ok",
            "seed": 1,
            "motor_r_s_ohm": f,
            "faults": 0,
            "complete": True,
            "speed_error_max_rpm": 0.1 * (i + 1),
        }
        for i, f in enumerate([0.95, 1.05])
    ]
    write_table(out, rows, ["motor_r_s_ohm"])
    (out / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (out / "sweep.json").write_text(
        json.dumps(
            {
                "name": "old",
                "axes": [
                    {
                        "name": "motor_r_s_ohm",
                        "field": "motor.r_s_ohm",
                        "kind": "normal",
                        "relative": True,
                    }
                ],
            }
        )
    )


def test_an_older_directory_is_read_with_its_factor_named_so_and_not_resumed(tmp_path, data):
    out = tmp_path / "old"
    _old_directory(out)
    report = write_report(out)
    assert "motor_r_s_ohm as motor_r_s_factor" in report.notes[0]
    assert [m.metric for m in report.stats] == ["faults", "complete", "speed_error_max_rpm"]
    assert (out / "report" / "speed_error_max_rpm.png").is_file()
    assert "Note: " in (out / "report" / "summary.md").read_text()
    sweep = tmp_path / "s.yaml"
    sweep.write_text(
        f"name: old\nprofile: {data / 'short.yaml'}\n"
        "axes:\n  - {field: motor.r_s_ohm, values: [0.95, 1.05], relative: true}\n"
    )
    with pytest.raises(ResultsFormatError) as e:
        run_sweep(load_sweep(sweep), out, workers=1, progress=False)
    assert str(e.value).startswith(f"{out / 'sweep.json'}: format = 1, not 2: {out} holds")
    assert json.loads((out / "sweep.json").read_text()).get("format") is None  # left alone
    r = _cli("sweep", str(sweep), "--out", str(out), "--no-progress")
    assert r.returncode == 2 and "format = 1, not 2" in r.stderr and "Traceback" not in r.stderr


def test_report_counts_the_runs_that_never_converged():
    from pmsm_hil.sweep.report import metric_stats

    nan = float("nan")
    rows = [
        {"status": "ok", "id_rls_l_d_h_conv_s": 0.4, "seg0_recovery_s": nan},
        {"status": "ok", "id_rls_l_d_h_conv_s": nan, "seg0_recovery_s": nan},
        {"status": "ok", "id_rls_l_d_h_conv_s": 0.6, "seg0_recovery_s": 0.1},
        {"status": "failed", "id_rls_l_d_h_conv_s": nan, "seg0_recovery_s": nan},
    ]
    conv, rec = metric_stats(rows, ["id_rls_l_d_h_conv_s", "seg0_recovery_s"])
    assert (conv.runs, conv.no_value, conv.median) == (2, 1, 0.5)
    assert conv.runs_text() == "2 (1 never)"  # the failed run is not counted
    assert rec.runs_text() == "1 (2 no value)"
    full = metric_stats(rows[2:3], ["id_rls_l_d_h_conv_s"])[0]
    assert full.runs_text() == "1"


@pytest.mark.parametrize(
    "values, says",
    [
        ("[1, 1.5]", "values[1] = 1.5 is not a whole number"),
        ("[1, two]", "values[1] = 'two' is not a whole number"),
        ("[1, -2]", "values[1] = -2 is not a whole number in 0..2147483647"),
        ("[3, 3.0]", "repeats a seed"),
    ],
)
def test_a_seed_axis_takes_distinct_whole_seeds(tmp_path, values, says):
    p = tmp_path / "s.yaml"
    p.write_text(f"name: s\nprofile: paper-a\naxes:\n  - {{field: seed, values: {values}}}\n")
    r = _cli("sweep", str(p), "--out", str(tmp_path / "out"))
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"{p}:4: axes[0]." in r.stderr and says in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize(
    "axis, says",
    [
        (
            "{field: motor.r_s_ohm, uniform: {low: 2, high: 1}}",
            "axes[0].uniform = {high: 1, low: 2} high 1 is below low 2",
        ),
        (
            "{field: motor.r_s_ohm}",
            "axes[0] = {field: motor.r_s_ohm} give exactly one of values, linspace, uniform, "
            "normal, log_uniform",
        ),
    ],
)
def test_an_axis_the_file_schema_refuses_is_said_in_the_sweeps_words(tmp_path, axis, says):
    """No pydantic "value error, " before the message (it was there)."""
    p = tmp_path / "s.yaml"
    p.write_text(f"name: s\nprofile: paper-a\ndraws: 2\naxes:\n  - {axis}\n")
    with pytest.raises(ProfileError) as e:
        load_sweep(p)
    assert f"{p}:5: {says}" in str(e.value) and "value error" not in str(e.value).lower()


@pytest.mark.parametrize(
    "axis, line_says",
    [
        (
            "{field: rig.effects.dead_time.dead_time_s, values: [1.0e-6, -3.0e-6]}",
            "axes[0].values[1] = -3e-06 makes the rig file invalid: "
            "effects.dead_time.dead_time_s = -3e-06 is outside the allowed range",
        ),
        (
            "{field: motor.r_s_ohm, relative: true, uniform: {low: -0.5, high: 1.1}}",
            "axes[0].uniform.low = -0.5 makes the motor file invalid: r_s_ohm = -0.45 is "
            "outside the allowed range (0, 1000] ohm (the factor -0.5 times the base value)",
        ),
        (
            "{field: rig.effects.dead_time.v_drop_v, values: [1.0, two]}",
            "axes[0].values[1] = 'two' makes the rig file invalid: effects.dead_time.v_drop_v = "
            "'two' is not a number",
        ),
        (
            "{field: motor.r_s_ohm, values: [1.0, '0.9']}",
            "axes[0].values[1] = '0.9' makes the motor file invalid: r_s_ohm = '0.9' is not a "
            "number (write numbers without quotes)",  # strict, as the motor file itself
        ),
        (
            "{field: motor.r_s_ohm, values: [1.0, .nan]}",
            "axes[0].values[1] = nan is not a finite number",  # once, not per type of the union
        ),
        (
            "{field: motor.r_s_ohm, relative: true, values: [1, two]}",
            "axes[0].values[1] = 'two' is not a number (a relative axis takes factors",
        ),
        (
            "{field: motor.l_d_h, log_uniform: {low: 1.0e-3, high: 50.0}}",
            "axes[0].log_uniform.high = 50 makes the motor file invalid: l_d_h = 50 is outside",
        ),
    ],
)
def test_a_value_the_files_do_not_take_is_named_at_the_sweep_files_line(tmp_path, axis, line_says):
    """Checked while planning (exit 2 before anything runs), not at run time in a generated file."""
    p = tmp_path / "s.yaml"
    draws = "draws: 2" if "values" not in axis else "seed: 1"
    p.write_text(f"name: s\nprofile: paper-a\n{draws}\naxes:\n  - {axis}\n")
    with pytest.raises(ProfileError) as e:
        run_sweep(load_sweep(p, defer=True), tmp_path / "out", workers=1, progress=False)
    assert str(e.value).startswith(f"{p}:5: {line_says}"), str(e.value)
    assert len(e.value.problems) == 1, str(e.value)
    assert not (tmp_path / "out" / "results.csv").exists()


def test_values_the_files_take_plan_as_before(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(
        "name: s\nprofile: paper-a\ndraws: 2\naxes:\n"
        "  - {field: rig.effects.dead_time.dead_time_s, values: [0.0, 2.0e-6]}\n"
        "  - {field: motor.r_s_ohm, relative: true, normal: {mean: 1.0, std: 0.05}}\n"
    )
    from pmsm_hil.sweep.plan import plan_runs

    runs = plan_runs(load_sweep(p, defer=True))
    assert [r.values["rig_effects_dead_time_dead_time_s"] for r in runs] == [0.0, 2e-6] * 2


def test_an_unquoted_indexed_field_in_braces_gets_the_hint_to_quote_it(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(
        "name: s\nprofile: paper-a\naxes:\n  - {field: profile.segments[1].load_nm, values: [1]}\n"
    )
    with pytest.raises(ProfileError) as e:
        load_sweep(p)
    assert str(e.value).startswith(f"{p}:4:29: invalid YAML: expected ',' or '}}', but got '['")
    assert str(e.value).endswith(
        "quote a field with an index inside {...}: 'profile.segments[1].load_nm'"
    )


def test_report_summary_names_the_runs_that_failed():
    from pmsm_hil.sweep.report import _summary

    rep = SimpleNamespace(
        headline=lambda: "2 runs",
        notes=[],
        stats=[],
        failed=[(1, "run error: the link dropped")],
        stopped=[],
    )
    text = _summary(rep)  # type: ignore[arg-type]
    assert "## Runs that failed to run" in text and "- run 1: run error: the link dropped" in text


def test_summary_shows_relative_errors_in_percent_as_the_console_does():
    from pmsm_hil.sweep.report import MetricStats, _summary

    rep = SimpleNamespace(
        headline=lambda: "2 runs",
        notes=[],
        failed=[],
        stopped=[],
        stats=[
            MetricStats("id_rls_l_d_h_error_rel", 2, 0.005, -0.0125, -0.0125, 0.005),
            MetricStats("speed_error_max_rpm", 2, 1.5, 2.25, 1.0, 2.25),
        ],
    )
    text = _summary(rep)  # type: ignore[arg-type]
    assert "| id_rls_l_d_h_error_rel | 2 | +0.50 % | -1.25 % | -1.25 % | +0.50 % |" in text
    assert "| speed_error_max_rpm | 2 | 1.5 | 2.25 | 1 | 2.25 |" in text


def test_sweep_report_help_is_the_reports_own(capsys, tmp_path, monkeypatch):
    """`sweep report --help` used to print the sweep's usage (SWEEP, --limit, --scheduler...):
    `report` is a value of the sweep's first argument. It now prints the report's; a file named
    `report` here is a sweep file, and then the sweep's help is what is asked for."""
    from pmsm_hil.cli.main import main

    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "report", "--help"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("usage: pmsm-hil sweep report [-h] DIR")
    assert "summary.md" in text and "--scheduler" not in text
    (tmp_path / "report").write_text("")
    with pytest.raises(SystemExit) as e:
        main(["sweep", "report", "--help"])
    assert e.value.code == 0
    assert "--scheduler" in capsys.readouterr().out
