"""Sweeps: the sweep file's validation, the plan, runs on Dask equal to `pmsm-hil run`, resume,
failed runs as results, the report."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from cli_helpers import CLI, cli
from emu_helpers import DEVICE_TOPICS, raw_messages

from pmsm_hil.profiles import ProfileError
from pmsm_hil.sweep import load_sweep, plan_runs, read_table, run_sweep


def device_messages(path) -> list:
    """raw_messages of the device topics, less the host's own notes in /pmsm/events (they name the
    transport: "started short on in-process emulator" against "... on emulator /dev/pts/5")."""
    from pmsm_hil.log.reader import read_log

    kinds = [str(k) for k in read_log(path).topic("/pmsm/events")["kind"]]
    events = raw_messages(path, ("/pmsm/events",))
    assert len(kinds) == len(events)
    device = [m for m, k in zip(events, kinds, strict=False) if k != "host"]
    assert len(device) >= 4  # segment starts, profile done
    return raw_messages(path, [t for t in DEVICE_TOPICS if t != "/pmsm/events"]) + device


def write_sweep(tmp_path: Path, body: str, name: str = "s.yaml") -> Path:
    p = tmp_path / name
    p.write_text(body)
    return p


def short_sweep(tmp_path, data, axes: str, extra: str = "") -> Path:
    return write_sweep(tmp_path, f"name: t\nprofile: {data / 'short.yaml'}\n{extra}axes:\n{axes}")


# ------------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    "body, line, field, text",
    [
        (
            "name: t\nprofile: paper-a\naxes:\n  - {field: motor.r_s_ohm, values: [1], uniform: {low: 0, high: 1}}\n",
            4,
            "axes[0]",
            "exactly one of",
        ),
        (
            "name: t\nprofile: paper-a\naxes:\n  - field: motor.r_s_ohm\n    normal: {mean: 1, std: 0}\n",
            5,
            "axes[0].normal.std",
            "must be > 0",
        ),
        (
            "name: t\nprofile: paper-a\naxes:\n  - {field: motor.r_s_ohm, uniform: {low: 0.9, high: 1.1}}\n",
            1,
            "draws",
            "is missing",
        ),
        ("name: t\nprofile: paper-a\nmetrics: [speed_eror]\n", 3, "metrics[0]", "is not one of"),
        (
            "name: t\nprofile: no-such-profile\n",
            2,
            "profile",
            "neither a file nor a shipped profile",
        ),
        (
            "name: t\nprofile: paper-a\naxes:\n  - {field: Motor.r, values: [1]}\n",
            4,
            "axes[0].field",
            "is not seed",
        ),
        ("name: t\nprofile: paper-a\nkeep_log: true\n", 3, "keep_log", "did you mean 'keep_logs'"),
    ],
)
def test_sweep_file_errors_name_file_line_field(tmp_path, body, line, field, text):
    p = write_sweep(tmp_path, body)
    with pytest.raises(ProfileError) as e:
        load_sweep(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}:{line}: {field}"), msg
    assert text in msg


def test_the_files_mistakes_come_in_one_report(tmp_path):
    """A missing `draws` and an axis naming no field of the base files: both at once (what the CLI
    does: load_sweep(defer=True), then plan_runs), not one per round."""
    p = write_sweep(
        tmp_path,
        "name: t\nprofile: paper-a\naxes:\n  - {field: motor.r_s_ohmz, values: [0.8]}\n"
        "  - {field: rig.effects.dead_time.dead_time_s, uniform: {low: 1.0e-6, high: 3.0e-6}}\n",
    )
    with pytest.raises(ProfileError) as e:
        load_sweep(p)  # without defer: the file's own problems first, as before
    assert "draws is missing" in str(e.value) and "r_s_ohmz" not in str(e.value)
    with pytest.raises(ProfileError) as e:
        plan_runs(load_sweep(p, defer=True))
    msg = str(e.value)
    assert "draws is missing" in msg
    assert f"{p}:4: axes[0].field = 'motor.r_s_ohmz' names no field of the motor" in msg
    r = subprocess.run(
        [sys.executable, "-m", "pmsm_hil.cli.main", "sweep", str(p), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2 and "draws is missing" in r.stderr and "r_s_ohmz" in r.stderr


def test_an_axis_naming_no_field_is_reported_at_its_line(tmp_path):
    """With what is there instead: the nearest name, the list's length, the value it is."""
    p = write_sweep(
        tmp_path,
        "name: t\nprofile: paper-a\naxes:\n  - {field: seed, values: [1]}\n"
        "  - {field: rig.effects.dead_time.dead_tme_s, values: [1e-6]}\n"
        "  - {field: 'profile.segments[13].load_nm', values: [1.0]}\n"
        "  - {field: motor.r_s_ohm.x, values: [1.0]}\n",
    )
    with pytest.raises(ProfileError) as e:
        plan_runs(load_sweep(p))
    assert str(e.value).splitlines() == [
        f"{p}:5: axes[1].field = 'rig.effects.dead_time.dead_tme_s' names no field of the rig "
        "('dead_tme_s' is unknown; did you mean 'dead_time_s'?)",
        f"{p}:6: axes[2].field = 'profile.segments[13].load_nm' names no field of the profile "
        "(segments has 13 items: 0..12)",
        f"{p}:7: axes[3].field = 'motor.r_s_ohm.x' names no field of the motor "
        "(r_s_ohm is a value, it has no 'x')",
    ]


def test_cli_reports_a_bad_sweep_file_without_traceback(tmp_path):
    p = write_sweep(tmp_path, "name: t\nprofile: paper-a\ndraws: 0\n")
    r = subprocess.run(
        [*CLI, "sweep", str(p), "--out", str(tmp_path / "o")], capture_output=True, text=True
    )
    assert r.returncode == 2
    assert f"{p}:3: draws = 0 is outside the allowed range [1, 100000]" in r.stderr.replace(
        "\n", ""
    )
    assert "Traceback" not in r.stderr


def test_cli_refuses_an_out_that_is_a_file_before_any_cluster(tmp_path):
    """--out at a file is bad input (exit 2) named as such; it used to surface from the cluster
    as 'cannot reach the scheduler None: File exists' (exit 3)."""
    blocker = tmp_path / "afile"
    blocker.write_text("")
    r = cli("sweep", "tolerance", "--out", blocker, "--limit", 1, timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"--out {blocker}: is a file; give a folder" in r.stderr
    assert "scheduler" not in r.stderr and "Traceback" not in r.stderr
    assert blocker.read_text() == ""


def test_cli_sweep_limit_runs_the_first_runs(tmp_path, data):
    p = short_sweep(
        tmp_path, data, "  - {field: seed, values: [1, 2, 3]}\n", extra="metrics: [faults]\n"
    )
    out = tmp_path / "o"
    r = subprocess.run(
        [
            *CLI,
            "sweep",
            str(p),
            "--out",
            str(out),
            "--limit",
            "1",
            "--workers",
            "1",
            "--no-progress",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert (
        "3 runs of short.yaml, the first 1" in r.stdout
        and "runs: 1 completed, 0 failed to run, 0 done before" in r.stdout
    )
    rows = read_table(out)
    assert [(x["index"], x["seed"], x["status"], x["faults"]) for x in rows] == [(0, 1, "ok", 0)]
    r = subprocess.run(
        [*CLI, "sweep", str(p), "--out", str(out), "--limit", "0"], capture_output=True, text=True
    )
    assert r.returncode == 2 and "--limit = 0 must be >= 1" in r.stderr


# ------------------------------------------------------------------------------- plan


def test_plan_is_grid_times_draws_and_reproducible(tmp_path, data):
    p = short_sweep(
        tmp_path,
        data,
        "  - {field: seed, values: [1, 2, 3]}\n"
        "  - {field: motor.r_s_ohm, normal: {mean: 1.0, std: 0.1}, relative: true}\n"
        "  - {field: rig.effects.encoder.lines, linspace: {start: 1000, stop: 2000, num: 2}}\n",
        extra="draws: 4\ndraw_seed: 5\n",
    )
    runs = plan_runs(load_sweep(p))
    assert len(runs) == 4 * 3 * 2
    assert [r.key for r in runs] == [r.key for r in plan_runs(load_sweep(p))]
    assert len({r.key for r in runs}) == len(runs)
    # one draw is shared by its grid points; the draws differ
    assert len({r.values["motor_r_s_factor"] for r in runs[:6]}) == 1
    assert len({r.values["motor_r_s_factor"] for r in runs}) == 4
    assert [r.seed for r in runs[:6]] == [1, 1, 2, 2, 3, 3]
    # relative: a factor on the motor file's value (0.9 ohm), the ohms beside it; an int field
    # stays an int
    r = runs[0]
    assert r.values["motor_r_s_ohm"] == 0.9 * r.values["motor_r_s_factor"]
    assert f"r_s_ohm: {r.values['motor_r_s_ohm']!r}" in r.texts["motor.yaml"]
    assert "lines: 1000\n" in r.texts["rig.yaml"] and "lines: 2000\n" in runs[1].texts["rig.yaml"]


# ------------------------------------------------------------------------------- runs


@pytest.fixture(scope="module")
def dead_time_sweep(tmp_path_factory):
    """Two runs of tests/data/short.yaml on one worker, logs kept."""
    tmp = tmp_path_factory.mktemp("sweep")
    data = Path(__file__).parent / "data"
    p = short_sweep(
        tmp,
        data,
        "  - {field: rig.effects.dead_time.dead_time_s, values: [1.0e-6, 3.0e-6]}\n"
        "  - {field: seed, values: [3]}\n",
        extra="keep_logs: true\nmetrics: [speed_error, recovery, faults, completeness]\n",
    )
    sweep = load_sweep(p)
    res = run_sweep(sweep, tmp / "out", workers=1, progress=False)
    return sweep, res


def test_a_sweep_run_equals_pmsm_hil_run_bit_for_bit(dead_time_sweep, tmp_path):
    _sweep, res = dead_time_sweep
    assert res.ok == 2 and res.failed == 0
    row = res.rows[1]
    assert row["status"] == "ok" and row["complete"] is True and row["faults"] == 0
    assert row["rig_effects_dead_time_dead_time_s"] == 3.0e-6
    inputs = res.out / "runs" / row["key"]
    assert "dead_time_s: 3.0e-06" in (inputs / "rig.yaml").read_text()
    cli_log = tmp_path / "cli.mcap"
    r = subprocess.run(
        [
            *CLI,
            "run",
            str(inputs / "profile.yaml"),
            "--seed",
            "3",
            "--out",
            str(cli_log),
            "--no-live",
        ],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert r.returncode == 0, r.stderr
    ours, theirs = device_messages(row["log_path"]), device_messages(cli_log)
    assert len(ours) > 5000
    assert ours == theirs
    # and the other run (other dead time) differs
    assert device_messages(res.rows[0]["log_path"]) != ours


def test_results_table_has_a_row_per_run_with_inputs_and_metrics(dead_time_sweep):
    _sweep, res = dead_time_sweep
    rows = read_table(res.out)
    assert [r["index"] for r in rows] == [0, 1]
    assert [r["rig_effects_dead_time_dead_time_s"] for r in rows] == [1.0e-6, 3.0e-6]
    for r in rows:
        assert r["seed"] == 3 and r["status"] == "ok" and Path(r["log_path"]).is_file()
        assert abs(r["speed_error_max_rpm"]) < 5.0
        assert r["seg1_recovery_s"] < 0.3
    csv = (res.out / "results.csv").read_text().splitlines()
    assert len(csv) == 3 and "rig_effects_dead_time_dead_time_s" in csv[0]


def test_resume_skips_the_runs_done(tmp_path, data):
    p = short_sweep(
        tmp_path, data, "  - {field: seed, values: [1, 2, 3]}\n", extra="metrics: [faults]\n"
    )
    sweep = load_sweep(p)
    first = run_sweep(sweep, tmp_path / "out", limit=1, workers=1, progress=False)
    assert (first.planned, first.ok, first.skipped) == (1, 1, 0)
    again = run_sweep(sweep, tmp_path / "out", workers=1, progress=False)
    assert (again.planned, again.ok, again.skipped) == (3, 2, 1)
    lines = [json.loads(x) for x in (tmp_path / "out" / "results.jsonl").read_text().splitlines()]
    assert sorted(x["index"] for x in lines) == [0, 1, 2]  # run 0 was not run again
    assert len(read_table(tmp_path / "out")) == 3
    third = run_sweep(sweep, tmp_path / "out", workers=1, progress=False)
    assert (third.ok, third.skipped) == (0, 3)


def test_a_failing_run_is_a_failed_row_not_a_failed_sweep(tmp_path, data):
    # 9000 r/min is beyond the motor's speed_max_rpm: that run cannot be made, the other runs
    p = short_sweep(
        tmp_path,
        data,
        "  - {field: 'profile.segments[0].speed_rpm', values: [500, 9000]}\n",
        extra="metrics: [faults]\n",
    )
    res = run_sweep(load_sweep(p), tmp_path / "out", workers=1, progress=False)
    assert (res.ok, res.failed) == (1, 1)
    bad = res.rows[1]
    assert bad["status"] == "failed"
    assert "profile.yaml" in bad["error"] and "segments[0].speed_rpm = 9000" in bad["error"]
    assert res.rows[0]["status"] == "ok"


def _crashing_task(task):
    """Kills its worker: run 0 on its first attempt only (a marker file), run 1 always."""
    from pmsm_hil.sweep import execute_run

    marker = Path(task["log_path"]).parent / "crashed-once"
    if task["index"] == 1 or (task["index"] == 0 and not marker.exists()):
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.touch()
        os._exit(9)
    return execute_run(task)


def test_a_run_whose_worker_dies_is_retried_once_then_failed(tmp_path, data):
    p = short_sweep(
        tmp_path,
        data,
        "  - {field: seed, values: [1, 2, 3]}\n",
        extra="metrics: [faults]\nkeep_logs: true\n",
    )
    res = run_sweep(
        load_sweep(p), tmp_path / "out", workers=1, progress=False, task_fn=_crashing_task
    )
    status = [r["status"] for r in res.rows]
    assert status == ["ok", "failed", "ok"], [r.get("error") for r in res.rows]
    assert "worker died" in res.rows[1]["error"]


def test_report_plots_each_metric_and_a_pass_map_for_a_2d_grid(tmp_path, data):
    p = short_sweep(
        tmp_path,
        data,
        "  - {field: seed, values: [1, 2]}\n"
        "  - {field: 'profile.segments[1].load_nm', values: [2.0, 5.0]}\n",
        extra="metrics: [speed_error, faults, completeness]\n",
    )
    out = tmp_path / "out"
    run_sweep(load_sweep(p), out, workers=1, progress=False)
    (out / "report").mkdir()
    (out / "report" / "ident_rls_l_d_h_err.png").write_bytes(b"an earlier report's plot")
    r = subprocess.run([*CLI, "sweep", "report", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rep = out / "report"
    assert not (rep / "ident_rls_l_d_h_err.png").exists()  # not this sweep's: removed
    assert (rep / "pass_map.png").stat().st_size > 1000
    assert (rep / "speed_error_max_rpm.png").stat().st_size > 1000
    summary = (rep / "summary.md").read_text()
    assert (
        "4 runs: 4 completed, 0 failed to run; the profile has no acceptance criteria: " in summary
    )
    assert "4 of 4 played the whole profile without a fault" in summary
    assert "| speed_error_max_rpm | 4 |" in summary
    r = subprocess.run([*CLI, "sweep", "report", str(tmp_path)], capture_output=True, text=True)
    assert r.returncode == 2 and "no results.parquet" in r.stderr


def test_random_draws_stay_in_their_ranges_and_overrides_apply(tmp_path, data):
    p = write_sweep(
        tmp_path,
        f"name: t\nprofile: {data / 'short.yaml'}\nrig: ideal\ndraws: 50\naxes:\n"
        "  - {field: rig.effects.dead_time.dead_time_s, uniform: {low: 1.0e-6, high: 2.0e-6}}\n"
        "  - {field: motor.j_kgm2, log_uniform: {low: 0.001, high: 0.1}}\n",
    )
    runs = plan_runs(load_sweep(p))
    dt = [r.values["rig_effects_dead_time_dead_time_s"] for r in runs]
    j = [r.values["motor_j_kgm2"] for r in runs]
    assert all(1e-6 <= x <= 2e-6 for x in dt) and all(1e-3 <= x <= 0.1 for x in j)
    assert min(j) < 0.01 < max(j)  # log-uniform: a decade each side
    assert "name: ideal" in runs[0].texts["rig.yaml"]  # the sweep's rig, not the profile's
    assert (
        "dead_time:\n    dead_time_s:" in runs[0].texts["rig.yaml"]
    )  # an effect the rig lacked, added


def test_relative_axis_on_a_field_without_a_number_is_an_error(tmp_path):
    p = write_sweep(
        tmp_path,
        "name: t\nprofile: paper-a\naxes:\n  - {field: rig.v_dc_v, values: [0.9], "
        "relative: true}\n",
    )
    with pytest.raises(ProfileError) as e:
        plan_runs(load_sweep(p))
    assert str(e.value).startswith(
        f"{p}:4: axes[0].relative = true needs a number in the base file, which has None"
    )


def test_another_sweep_into_the_same_folder_is_refused(tmp_path, data):
    one = short_sweep(
        tmp_path, data, "  - {field: seed, values: [1]}\n", extra="metrics: [faults]\n"
    )
    out = tmp_path / "out"
    run_sweep(load_sweep(one), out, workers=1, progress=False)
    other = write_sweep(
        tmp_path,
        f"name: other\nprofile: {data / 'short.yaml'}\naxes:\n  - {{field: seed, values: [2]}}\n",
        name="other.yaml",
    )
    r = subprocess.run(
        [*CLI, "sweep", str(other), "--out", str(out)], capture_output=True, text=True
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"{out / 'sweep.json'}: name = 't': {out} holds the results of sweep 't'" in r.stderr
    assert "not of 'other'" in r.stderr
    assert json.loads((out / "sweep.json").read_text())["name"] == "t"  # left alone
    # the same sweep, edited (another seed), resumes into it: the first run is not run again
    edited = short_sweep(
        tmp_path, data, "  - {field: seed, values: [1, 2]}\n", extra="metrics: [faults]\n"
    )
    res = run_sweep(load_sweep(edited), out, workers=1, progress=False)
    assert (res.skipped, res.ok) == (1, 1)
