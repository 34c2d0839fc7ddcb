"""Axes whose values are names, not numbers: a whole rig or motor file per run (`{field: rig,
values: [default, lab-typical]}`), a profile's choice (`control.current_ref: [mtpa, id_zero]`),
in the plan, the results and the report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pmsm_hil.sweep import write_table
from pmsm_hil.sweep.report import write_report


def _named_results(out: Path) -> None:
    """A finished sweep of a name axis x a seed axis, as `sweep` leaves it."""
    out.mkdir()
    rows = [
        {
            "index": i,
            "key": f"k{i}",
            "status": "ok",
            "seed": seed,
            "rig": rig,
            "faults": 0,
            "complete": True,
            "speed_error_max_rpm": 0.1 * (i + 1),
        }
        for i, (rig, seed) in enumerate(
            (r, s) for r in ("default", "lab-typical") for s in (1, 2, 3)
        )
    ]
    write_table(out, rows, ["rig", "seed"])
    axes = [
        {"column": c, "value_column": None, "field": c, "kind": "values", "relative": False}
        for c in ("rig", "seed")
    ]
    meta = {"format": 2, "name": "named", "file": "s.yaml", "profile": "p.yaml", "axes": axes}
    (out / "sweep.json").write_text(json.dumps(meta))


def test_report_of_a_name_axis_plots_it_by_name_and_maps_the_grid(tmp_path):
    """Before, a grid of a name axis and another axis ended `sweep report` in a traceback
    (ValueError: Unknown format code 'g' for object of type 'str', at the pass map's ticks), and
    the metric plots had no panel for the names."""
    out = tmp_path / "out"
    _named_results(out)
    report = write_report(out)
    rep = out / "report"
    assert (rep / "pass_map.png").stat().st_size > 1000
    assert rep / "pass_map.png" in report.files
    assert (rep / "speed_error_max_rpm.png").stat().st_size > 1000
    assert report.completed == 6 and report.met == 6


def _sweep_file(tmp_path: Path, data: Path, axes: str, extra: str = "") -> Path:
    p = tmp_path / "s.yaml"
    p.write_text(f"name: rigs\nprofile: {data / 'short.yaml'}\n{extra}axes:\n{axes}")
    return p


def test_a_rig_axis_gives_each_run_that_rig_file(tmp_path, data):
    """`{field: rig, values: [...]}`: the runs of each rig are the profile as `--rig RIG` runs it
    (the same key), the name as written in the `rig` column; a relative axis on a rig field is a
    factor on that rig's own value. Before, the field `rig` was refused ("is not seed,
    profile.PATH, ...")."""
    import yaml

    from pmsm_hil.profiles.shipped import resolve
    from pmsm_hil.sweep import load_sweep, plan_runs
    from pmsm_hil.sweep.plan import profile_run

    (tmp_path / "my-rig.yaml").write_text(Path(resolve("ideal", "rig")).read_text())
    p = _sweep_file(
        tmp_path,
        data,
        "  - {field: rig, values: [default, lab-typical, my-rig.yaml]}\n"
        "  - {field: seed, values: [1, 2]}\n"
        "  - {field: rig.effects.dead_time.dead_time_s, values: [1.0], relative: true}\n",
    )
    runs = plan_runs(load_sweep(p))
    assert [(r.values["rig"], r.seed) for r in runs] == [
        (rig, seed) for rig in ("default", "lab-typical", "my-rig.yaml") for seed in (1, 2)
    ]
    dead_s = [r.values["rig_effects_dead_time_dead_time_s"] for r in runs]
    assert dead_s[0] == 2.0e-6 and dead_s[2] == 2.5e-6  # each rig's own dead time
    assert len({r.key for r in runs}) == 6
    lab = yaml.safe_load(runs[2].texts["rig.yaml"])
    assert lab["name"] == "lab-typical" and "saturation" in lab["effects"]
    mine = yaml.safe_load(runs[4].texts["rig.yaml"])
    assert mine["name"] == yaml.safe_load(Path(resolve("ideal", "rig")).read_text())["name"]
    # a rig axis's run is the profile run with that rig: one key, so `test --rig` and the sweep
    # agree (the relative factor 1.0 leaves the file's value as it is)
    alone = profile_run(str(data / "short.yaml"), seed=2, rig_path=resolve("lab-typical", "rig"))
    assert yaml.safe_load(alone.texts["rig.yaml"]) == yaml.safe_load(runs[3].texts["rig.yaml"])


def test_a_motor_axis_gives_each_run_that_motor_file(tmp_path, data):
    from pmsm_hil.sweep import load_sweep, plan_runs

    p = _sweep_file(
        tmp_path, data, "  - {field: motor, values: [paper-a-ipmsm, paper-a-ipmsm-measured]}\n"
    )
    runs = plan_runs(load_sweep(p))
    assert [r.values["motor"] for r in runs] == ["paper-a-ipmsm", "paper-a-ipmsm-measured"]
    assert "flux_map" in runs[1].texts["motor.yaml"]
    assert "flux_map" not in runs[0].texts["motor.yaml"]


@pytest.mark.parametrize(
    "extra, axes, says",
    [
        (
            "",
            "  - {field: rig, values: [default, lab-typcal]}\n",
            "s.yaml:4: axes[0].values[1] = 'lab-typcal' is neither a file nor a shipped rig; "
            "did you mean 'lab-typical'?",
        ),
        (
            "rig: default\n",
            "  - {field: rig, values: [default, lab-typical]}\n",
            "s.yaml:3: rig = 'default' is given and swept (axes[0]): remove one",
        ),
        (
            "",
            "  - {field: rig, values: [default, ideal, default]}\n",
            "s.yaml:4: axes[0].values[2] = 'default' repeats a rig file (the same runs twice)",
        ),
        (
            "draws: 2\n",
            "  - {field: motor, uniform: {low: 1, high: 2}}\n",
            "s.yaml:5: axes[0].field = 'motor' takes values: [...] of files or shipped names",
        ),
        (
            "",
            "  - {field: rig, values: [default, 3]}\n",
            "s.yaml:4: axes[0].values[1] = 3 is not a rig file or shipped name",
        ),
        (
            "",
            "  - {field: motor, values: [paper-a-ipmsm, weak.yaml]}\n",
            "s.yaml:4: axes[0].values[1] = 'weak.yaml' does not load with the profile "
            "(the problems below)\nshort.yaml:7: segments[1].load_nm = 5 is beyond",
        ),
        (
            "",
            "  - {field: rig, values: [default, lab-typical]}\n"
            "  - {field: rig.effects.dead_tme.dead_time_s, values: [1.0e-6]}\n",
            "s.yaml:5: axes[1].field = 'rig.effects.dead_tme.dead_time_s' names no field of the "
            "rig ('dead_tme' is unknown; did you mean 'dead_time'?)",
        ),
    ],
)
def test_a_file_axis_that_cannot_be_run_is_named_at_its_line(tmp_path, data, extra, axes, says):
    from pmsm_hil.profiles import ProfileError
    from pmsm_hil.profiles.shipped import resolve
    from pmsm_hil.sweep import load_sweep, plan_runs

    motor = Path(resolve("paper-a-ipmsm", "motor")).read_text()  # a motor too weak for the load
    (tmp_path / "weak.yaml").write_text(motor.replace("torque_max_nm: 18.3", "torque_max_nm: 3"))
    p = _sweep_file(tmp_path, data, axes, extra)
    with pytest.raises(ProfileError) as e:
        plan_runs(load_sweep(p, defer=True))
    assert says.split("\n")[0] in str(e.value)
    for line in says.split("\n")[1:]:
        assert line in str(e.value)


def test_a_sweep_over_two_rigs_runs_and_reports_by_rig(tmp_path, data):
    from pmsm_hil.sweep import load_sweep, read_table, run_sweep

    p = _sweep_file(
        tmp_path,
        data,
        "  - {field: rig, values: [ideal, lab-typical]}\n",
        extra="metrics: [speed_error, faults, completeness]\n",
    )
    out = tmp_path / "out"
    run_sweep(load_sweep(p), out, workers=1, progress=False)
    rows = read_table(out)
    assert [(r["rig"], r["status"], r["complete"]) for r in rows] == [
        ("ideal", "ok", True),
        ("lab-typical", "ok", True),
    ]
    assert rows[0]["speed_error_max_rpm"] != rows[1]["speed_error_max_rpm"]  # two plants
    write_report(out)
    assert (out / "report" / "speed_error_max_rpm.png").is_file()
