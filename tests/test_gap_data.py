"""Gap diagnosis data layer: the emulator's continuous control-rate recording, loading records from
logs, and `pmsm-hil import` of control-rate and steady-state CSV files."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.cli.main import main
from pmsm_hil.gap.csv_import import CsvImportError, read_csv
from pmsm_hil.gap.record import ControlRecord, SteadyRecord, load_record
from pmsm_hil.log.reader import read_log

ROOT = Path(__file__).resolve().parents[1]
MOTOR = str(ROOT / "profiles/motors/paper-a-ipmsm.yaml")


@pytest.fixture(scope="module")
def lab_log(tmp_path_factory):
    from pmsm_hil.gapgen.recorder import record_profile

    path = tmp_path_factory.mktemp("gap") / "lab.mcap"
    record_profile(
        ROOT / "tests/data/gap-short.yaml",
        path,
        rig_path=ROOT / "profiles/rigs/lab-typical.yaml",
        seed=3,
    )
    return path


def test_continuous_record_matches_the_triggered_capture(lab_log):
    log = read_log(lab_log)
    cap, cr = log.topic("/pmsm/capture"), log.topic("/pmsm/control_rate")
    assert len(cap["t_s"]) == 1024
    j = np.searchsorted(cr["t_s"], cap["t_s"] - 1e-7)
    assert np.max(np.abs(cr["t_s"][j] - cap["t_s"])) < 1e-6
    for k in ("s_a", "s_b", "s_c"):
        assert np.array_equal(cr[k][j], cap[k].astype(float))
    # the capture holds the wire's scaled integers: equal within their resolution
    assert np.max(np.abs(cr["i_a_a"][j] - cap["i_a_a"])) < 2e-3
    assert np.max(np.abs(cr["theta_e_rad"][j] - cap["theta_e_rad"])) < 1e-3
    # continuous: one row per control period
    assert np.allclose(np.diff(cr["t_s"]), 50e-6, rtol=1e-3)


def test_load_record_prefers_the_continuous_recording(lab_log):
    rec = load_record(lab_log)
    assert isinstance(rec, ControlRecord)
    assert rec.voltage_kind == "switch" and len(rec.runs) == 1
    assert rec.sensor_spec == {
        "i_noise_a": 0.02,
        "adc_lsb_a": 0.0244140625,
        "encoder_lines": 2500.0,
    }
    ab = rec.u_alpha_beta()
    assert np.max(np.abs(ab)) <= 2 / 3 * np.max(rec.v_dc_v) + 1e-9


def _write_csv(path, cols, n=None):
    names = list(cols)
    n = len(next(iter(cols.values()))) if n is None else n
    with open(path, "w") as f:
        f.write(",".join(names) + "\n")
        for i in range(n):
            f.write(",".join(repr(float(cols[c][i])) for c in names) + "\n")


def test_control_rate_csv_round_trip(lab_log, tmp_path):
    cr = read_log(lab_log).topic("/pmsm/control_rate")
    sl = slice(1000, 1600)
    cols = {
        k: cr[k][sl]
        for k in ("t_s", "i_a_a", "i_b_a", "s_a", "s_b", "s_c", "v_dc_v", "theta_e_rad")
    }
    _write_csv(tmp_path / "scope.csv", cols)
    out = tmp_path / "scope.mcap"
    assert main(["import", str(tmp_path / "scope.csv"), "--motor", MOTOR, "-o", str(out)]) == 0
    rec = load_record(out)
    assert rec.n == 600 and rec.ts_s == pytest.approx(50e-6, rel=1e-3)
    assert np.allclose(rec.i_abc[:, 0], cols["i_a_a"]) and np.all(np.isnan(rec.i_abc[:, 2]))
    assert np.array_equal(rec.v_cmd[:, 1], cols["s_b"])
    assert rec.sensor_spec == {}  # an imported CSV carries no sensor specification
    # omega from the angle when not given
    assert np.median(rec.omega_e_rad_s) == pytest.approx(
        np.median(cr["omega_e_rad_s"][sl]), rel=0.05
    )


@pytest.mark.parametrize(
    "cols,needle",
    [
        (
            {"t_s": 1, "i_a_a": 1, "i_b_a": 1, "s_a": 1, "s_b": 1, "s_c": 1, "v_dc_v": 1},
            "missing column(s) theta_e_rad",
        ),
        ({"t_s": 1, "i_a_a": 1, "i_b_a": 1, "theta_e_rad": 1, "v_dc_v": 1}, "the applied voltage"),
        (
            {"t_s": 1, "i_a_a": 1, "i_b_a": 1, "theta_e_rad": 1, "s_a": 1, "s_b": 1, "s_c": 1},
            "v_dc_v",
        ),
        (
            {
                "t_s": 1,
                "i_a_a": 1,
                "i_b_a": 1,
                "theta_e_rad": 1,
                "u_alpha_v": 1,
                "u_beta_v": 1,
                "i_a_mA": 1,
            },
            "unknown column(s) i_a_mA",
        ),
        ({"t_s": 1, "u_d_v": 1, "u_q_v": 1, "i_d_a": 1, "i_q_a": 1}, "omega_e_rad_s or speed_rpm"),
    ],
)
def test_csv_columns_named_in_the_error(tmp_path, capsys, cols, needle):
    n = 5
    data = {k: np.arange(n) * 1e-4 if k == "t_s" else np.zeros(n) for k in cols}
    p = tmp_path / "bad.csv"
    _write_csv(p, data)
    with pytest.raises(CsvImportError, match="line 1"):
        read_csv(p)
    assert main(["import", str(p), "--motor", MOTOR, "-o", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err
    assert needle in err and "bad.csv" in err and "Traceback" not in err


def _ok_cols(n=6):
    return {
        "t_s": np.arange(n) * 1e-4,
        "i_a_a": np.zeros(n),
        "i_b_a": np.zeros(n),
        "u_alpha_v": np.zeros(n),
        "u_beta_v": np.zeros(n),
        "theta_e_rad": np.zeros(n),
    }


def test_csv_gap_in_time_and_bad_values(tmp_path):
    c = _ok_cols()
    c["t_s"][4:] += 1e-4
    _write_csv(tmp_path / "gap.csv", c)
    with pytest.raises(CsvImportError, match=r"line 6: t_s = .* gap of 0.0002 s"):
        read_csv(tmp_path / "gap.csv")
    p = tmp_path / "nan.csv"
    _write_csv(p, _ok_cols())
    lines = p.read_text().splitlines()
    f = lines[3].split(",")
    f[1] = "abc"
    lines[3] = ",".join(f)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(CsvImportError, match=r"line 4: i_a_a = 'abc' is not a number"):
        read_csv(p)
    c = _ok_cols()
    c["t_s"][3] = c["t_s"][2]
    _write_csv(tmp_path / "mono.csv", c)
    with pytest.raises(CsvImportError, match=r"line 5: t_s = .* does not increase"):
        read_csv(tmp_path / "mono.csv")


def test_steady_state_csv(tmp_path):
    n = 10
    c = {
        "t_s": np.arange(n) * 0.5,
        "u_d_v": -np.ones(n),
        "u_q_v": 50 + np.arange(n),
        "i_d_a": np.zeros(n),
        "i_q_a": np.ones(n) * 3,
        "speed_rpm": np.full(n, 600.0),
        "torque_nm": np.ones(n),
    }
    _write_csv(tmp_path / "ss.csv", c)
    out = tmp_path / "ss.mcap"
    assert main(["import", str(tmp_path / "ss.csv"), "--motor", MOTOR, "-o", str(out)]) == 0
    rec = load_record(out)
    assert isinstance(rec, SteadyRecord)
    assert rec.omega_e_rad_s[0] == pytest.approx(600 * 4 * 2 * np.pi / 60)
    assert np.allclose(rec.u_dq[:, 1], c["u_q_v"])


def test_gap_runs_on_the_triggered_capture_alone(lab_log, tmp_path, capsys):
    from pmsm_hil.gap.record import GAP_TOPICS
    from pmsm_hil.log.writer import LogWriter

    log = read_log(lab_log)
    out = tmp_path / "capture-only.mcap"
    with LogWriter(
        out,
        {k: v for k, v in log.metadata.items() if k != "log"},
        [(a.name, a.media_type, a.data) for a in log.attachments],
        topics=GAP_TOPICS,
    ) as w:
        w.write_many("/pmsm/capture", log.topic("/pmsm/capture"))
    rec = load_record(out)
    assert rec.n == 1024 and rec.source.endswith("/pmsm/capture")
    assert main(["gap", str(out), "--json"]) == 0  # the motor from the log's attachment
    import json

    res = json.loads(capsys.readouterr().out)
    assert res["transitions"] == 1022 and res["effects"]
    # 51 ms hold no six settled plateaus: said once, not "settled plateaus: 0 settled plateaus"
    assert main(["gap", str(out)]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if "plateaus" in ln)
    n = res["plateaus"]["plateaus"]
    assert line == f"  settled plateaus: {n} found, the view needs 6: not used"
    # every figure of the evidence with its unit: "± 4.8 V^2, threshold 14 V^2", not "± 4.8, 14"
    ev = [e["evidence"] for e in res["effects"] if "MSE" in e["evidence"]]
    assert ev and all(re.search(r"± [-+.e\d]+ V\^2[,)]", x) for x in ev)
    assert all(
        re.search(r"threshold [-+.e\d]+ V\^2\)", x) for x in ev if re.search(r"threshold \d", x)
    )


def test_import_and_gap_take_a_shipped_motor_by_name(lab_log, tmp_path, capsys):
    """`--motor paper-a-ipmsm` as for `run`: a bare name is the shipped motor file; a name that is
    neither a file nor a shipped motor is a clear error naming it."""
    cr = read_log(lab_log).topic("/pmsm/control_rate")
    sl = slice(1000, 1400)
    cols = {
        k: cr[k][sl]
        for k in ("t_s", "i_a_a", "i_b_a", "s_a", "s_b", "s_c", "v_dc_v", "theta_e_rad")
    }
    _write_csv(tmp_path / "scope.csv", cols)
    out = tmp_path / "scope.mcap"
    assert (
        main(["import", str(tmp_path / "scope.csv"), "--motor", "paper-a-ipmsm", "-o", str(out)])
        == 0
    )
    assert load_record(out).n == 400
    capsys.readouterr()
    assert main(["gap", str(out), "--motor", "paper-a-ipmsm", "--json"]) == 0
    assert '"effects"' in capsys.readouterr().out
    assert main(["gap", str(out), "--motor", "no-such-motor"]) == 2
    assert "no-such-motor" in capsys.readouterr().err


def test_csv_with_a_byte_order_mark_imports(tmp_path):
    """Excel's "CSV UTF-8" starts with a byte-order mark: it is not part of the first column's
    name."""
    p = tmp_path / "excel.csv"
    _write_csv(p, _ok_cols())
    p.write_text(p.read_text(), encoding="utf-8-sig")
    assert p.read_bytes().startswith(b"\xef\xbb\xbf")
    kind, cols = read_csv(p)
    assert kind == "control" and next(iter(cols)) == "t_s"
    assert main(["import", str(p), "--motor", MOTOR, "-o", str(tmp_path / "x.mcap")]) == 0
    # another encoding (Excel's plain "CSV" on Windows: cp1252) is named, not a traceback
    p.write_bytes(
        p.read_text(encoding="utf-8-sig").replace("t_s", "t_s # \u00b5s", 1).encode("cp1252")
    )
    with pytest.raises(
        CsvImportError, match=r"excel.csv: line 1: not UTF-8 text \(octet 6 = 0xb5: "
    ):
        read_csv(p)


def test_csv_not_utf8_names_the_line_and_the_octet_in_the_file(tmp_path, capsys):
    """A byte that is not UTF-8 far into the file (past the reader's first chunk) is named by its
    line and its offset in the file, not in the chunk the decoder was reading."""
    p = tmp_path / "scope.csv"
    _write_csv(p, _ok_cols(2000))
    text = p.read_bytes()
    p.write_bytes(text + "# Temperatur 25 \u00b0C\n".encode("latin-1"))
    octet = len(text) + len(b"# Temperatur 25 ")
    with pytest.raises(
        CsvImportError, match=rf"line 2002: not UTF-8 text \(octet {octet} = 0xb0: "
    ):
        read_csv(p)
    assert main(["import", str(p), "--motor", MOTOR, "-o", str(tmp_path / "x.mcap")]) == 2
    assert "line 2002" in capsys.readouterr().err


@pytest.mark.parametrize(
    "change,needle",
    [
        (
            lambda c: c["t_s"].__setitem__(3, c["t_s"][2]),
            "line 5: t_s = 0.0002 does not increase (previous 0.0002)",
        ),
        (
            lambda c: c.update(
                s_a=np.zeros(6),
                s_b=np.zeros(6),
                s_c=np.array([0, 0, 0, 0, 2.0, 1]),
                v_dc_v=np.full(6, 540.0),
            ),
            "line 6: s_c = 2.0 is not 0 or 1",
        ),
        (
            lambda c: c["t_s"].__imul__(1000),
            "t_s = 0.1: the sample time from t_s is 0.1 s, not a "
            "control period (1e-06 .. 0.001 s: one row per PWM period); t_s is in seconds — is it "
            "written in milliseconds (100 us a period)?",
        ),
        (lambda c: c["t_s"].__imul__(1e6), "is it written in microseconds (100 us a period)?"),
        (
            lambda c: c["t_s"].__imul__(1e-3),
            "sample time from t_s is 1e-07 s, not a control period",
        ),
        (
            lambda c: c.update(pwm_on=np.array([1, 1, 1, 5.0, 1, 1])),
            "line 5: pwm_on = 5.0 is not 0 or 1",
        ),
        (  # a wrapped angle in degrees: 359 -> 3 is no step of one row in radians
            lambda c: c.update(theta_e_rad=np.array([350, 355, 359, 3.0, 8, 13])),
            "line 5: theta_e_rad = 3.0 after 359.0: a step of more than one turn (2 pi rad) in "
            "one row; theta_e_rad is in radians — is it written in degrees?",
        ),
        (  # paper-a-ipmsm trips at 25 A: 1.5 A written in mA
            lambda c: c["i_a_a"].__setitem__(2, 1500.0),
            "line 4: i_a_a = 1500.0 is more than 10 times the motor file's i_trip_a (25 A): "
            "i_a_a is in A — is it written in mA?",
        ),
        (
            lambda c: c["u_beta_v"].__setitem__(1, 12000.0),
            "line 3: u_beta_v = 12000.0 is more than 10 times the motor file's v_dc_max_v "
            "(750 V): u_beta_v is in V — is it written in mV?",
        ),
    ],
)
def test_csv_errors_quote_the_values_as_written(tmp_path, capsys, change, needle):
    """Plain numbers as the file writes them (no numpy reprs), and a sample time that is no
    control period (t_s written in milliseconds: a 100 us period reads 0.1 s) refused."""
    c = _ok_cols()
    change(c)
    if "u_alpha_v" in c and "s_a" in c:
        del c["u_alpha_v"], c["u_beta_v"]
    p = tmp_path / "bad.csv"
    _write_csv(p, c)
    assert main(["import", str(p), "--motor", MOTOR, "-o", str(tmp_path / "x.mcap")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert needle in err and "np.float64" not in err and "bad.csv" in err
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize(
    "text,needle",
    [
        (  # the header after comment lines: its own line is named, not line 1
            "# scope export\n# channel 1: phase a\nt_s,i_a_a,i_b_a,theta_e_rad,u_alpha_v\n",
            "bad.csv: line 3: control-rate data: missing column(s) the applied voltage",
        ),
        (
            "t_s,i_a_a,i_b_a,theta_e_rad,u_alpha_v,u_beta_v,\n",
            "bad.csv: line 1: column 7 of the header has no name",
        ),
        (
            "# exported\nt_s;i_a_a;i_b_a;theta_e_rad;u_alpha_v;u_beta_v\n",
            "bad.csv: line 2: the header 't_s;i_a_a;i_b_a;theta_e_rad;u_alpha_v;u_beta_v' is one "
            "column: the separator is a comma, not ';'",
        ),
        (
            "i_d_a,i_q_a,psi_d_wb,psi_q_wb\n",
            "bad.csv: line 1: a flux map (i_d_a, i_q_a, psi_d_wb, psi_q_wb), not control-rate or "
            "steady-state data",
        ),
    ],
)
def test_csv_header_problems_name_the_header_line(tmp_path, capsys, text, needle):
    p = tmp_path / "bad.csv"
    p.write_text(text + "".join(f"{k * 1e-4},0,0,0,0,0\n" for k in range(5)))
    assert main(["import", str(p), "--motor", MOTOR, "-o", str(tmp_path / "x.mcap")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert needle in err and "Traceback" not in err


def test_import_output_is_checked_first(tmp_path, capsys):
    """-o must be a writable *.mcap (as `run -o`), checked before the CSV is read: no traceback
    from the log writer, nothing left behind."""
    p = tmp_path / "ok.csv"
    _write_csv(p, _ok_cols())
    (tmp_path / "blocker").write_text("a file where a folder is wanted")
    for out, needle in (
        ("g.txt", "-o g.txt: the log is MCAP, name it *.mcap"),
        ("blocker/g.mcap", "-o blocker/g.mcap: cannot write there"),
    ):
        assert main(["import", str(p), "--motor", MOTOR, "-o", str(tmp_path / out)]) == 2
        err = capsys.readouterr().err
        assert needle.replace("-o ", f"-o {tmp_path}/") in " ".join(err.split())
        assert "Traceback" not in err
    assert sorted(x.name for x in tmp_path.iterdir()) == ["blocker", "ok.csv"]


def test_import_help_lists_the_columns(capsys):
    from pmsm_hil.cli import import_csv as cli_import
    from pmsm_hil.gap import csv_import

    with pytest.raises(SystemExit):
        main(["import", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    names = (
        csv_import.CONTROL_REQUIRED
        + tuple(c for g in csv_import.CONTROL_VOLTAGE for c in g)
        + csv_import.CONTROL_OPTIONAL
        + csv_import.STEADY_REQUIRED
        + csv_import.STEADY_SPEED
        + csv_import.STEADY_OPTIONAL
    )
    assert [n for n in names if n not in text] == []
    assert "docs/gap.md" in text
    # the sample-time bounds the help quotes are the importer's
    assert cli_import.TS_MIN_US * 1e-6 == csv_import.TS_MIN_S
    assert cli_import.TS_MAX_MS * 1e-3 == csv_import.TS_MAX_S


def test_import_and_record_keep_a_log_already_at_their_output(tmp_path, capsys):
    """`import -o` and `gap record -o` naming a file that is there (another run's log) refuse,
    as `run --out` does, and leave it as it was; `--overwrite` replaces it."""
    csv_path = tmp_path / "scope.csv"
    _write_csv(csv_path, _ok_cols(200))
    there = tmp_path / "there.mcap"
    there.write_bytes(b"another run's log")
    for argv in (
        ["import", str(csv_path), "--motor", MOTOR, "-o", str(there)],
        ["gap", "record", "diagnose", "--rig", "lab-typical", "-o", str(there)],
    ):
        assert main(argv) == 2, argv
        err = " ".join(capsys.readouterr().err.split())
        assert f"-o {there}: a file is there already; --overwrite replaces it" in err, argv
        assert there.read_bytes() == b"another run's log"
    assert main(["import", str(csv_path), "--motor", MOTOR, "-o", str(there), "--overwrite"]) == 0
    assert load_record(there).n == 200


@pytest.mark.parametrize(
    ("written", "refused"),
    [(1.0, False), (1.03, False), (60 / (2 * np.pi * 4), True), (1 / 4, True), (-1.0, True)],
)
def test_csv_speed_must_be_the_angles_rate(tmp_path, written, refused):
    """omega_e_rad_s beside theta_e_rad: their means over the file agree (a filtered speed's
    3 % is fine); the speed in r/min, the mechanical speed or the other sign is refused at the
    header's line, with what it averages against the angle's rate."""
    c = _ok_cols(400)
    w = 300.0  # rad/s electrical: 0.12 s in 400 rows of 100 us, over five turns
    c["theta_e_rad"] = np.mod(w * c["t_s"], 2 * np.pi)
    c["omega_e_rad_s"] = np.full(400, w * written)
    p = tmp_path / "speed.csv"
    _write_csv(p, c)
    if not refused:
        assert read_csv(p)[0] == "control"
        return
    with pytest.raises(
        CsvImportError, match=r"line 1: column omega_e_rad_s averages .* turns at 300 "
    ):
        read_csv(p)


@pytest.mark.parametrize("no_value", ["", "nan"])
def test_a_csv_of_a_whole_control_rate_topic_imports(lab_log, tmp_path, no_value):
    """Every column of /pmsm/control_rate exported as it is (pandas' to_csv writes its NaN, "not
    given", as empty cells; numpy as nan): the columns with no value in any row are not given, as
    in the log, and the import gives the record the log gives. A column with some values and some
    not stays an error."""
    log = read_log(lab_log)
    cr = log.topic("/pmsm/control_rate")
    sl = slice(1000, 1600)
    names = list(cr)
    assert np.all(np.isnan(cr["d_a"][sl])) and np.all(np.isnan(cr["u_alpha_v"][sl]))
    p = tmp_path / "export.csv"
    with open(p, "w") as f:
        f.write(",".join(names) + "\n")
        for i in range(sl.start, sl.stop):
            f.write(
                ",".join(no_value if np.isnan(cr[c][i]) else repr(float(cr[c][i])) for c in names)
                + "\n"
            )
    out = tmp_path / "export.mcap"
    assert main(["import", str(p), "--motor", MOTOR, "-o", str(out)]) == 0
    back = read_log(out).topic("/pmsm/control_rate")
    for c in names:
        np.testing.assert_array_equal(back[c], cr[c][sl], err_msg=c)
    rec = load_record(out)
    assert rec.voltage_kind == "switch" and rec.n == 600
    lines = p.read_text().splitlines()
    first = lines[1].split(",")
    first[names.index("d_a")] = "0.5"
    lines[1] = ",".join(first)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(CsvImportError, match=r"line 3: d_a = '(nan)?' is not (a number|finite)"):
        read_csv(p)


def test_a_voltage_group_without_values_is_named_as_not_given(tmp_path):
    c = _ok_cols()
    _write_csv(tmp_path / "v.csv", c)
    text = (tmp_path / "v.csv").read_text().splitlines()
    # the u group's cells emptied: no applied voltage is given
    rows = [text[0]] + [",".join([*r.split(",")[:3], "", "", *r.split(",")[5:]]) for r in text[1:]]
    (tmp_path / "v.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(CsvImportError) as e:
        read_csv(tmp_path / "v.csv")
    assert "the applied voltage" in str(e.value)
    assert "without a value in any row, so not given: u_alpha_v, u_beta_v" in str(e.value)


def test_gap_record_takes_the_motor_given(tmp_path, capsys):
    """`gap record --motor` replaces the profile's motor file as `run --motor` does (it was
    ignored: the SEW motor on the SEW rig was checked, and refused, as paper A's on 60 V). The
    diagnose profile's 1500 r/min is beyond the SEW motor's speed_max_rpm: the refusal names it."""
    out = tmp_path / "sew.mcap"
    argv = ["gap", "record", "diagnose", "--rig", "sew-cm3c80s", "-o", str(out)]
    assert main([*argv, "--motor", "sew-cm3c80s"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "motors/sew-cm3c80s.yaml" in err and "paper-a-ipmsm.yaml" not in err, err
    assert not out.exists()


def test_gap_record_of_a_run_that_faults_says_so_and_keeps_the_record(tmp_path, capsys):
    """A recording whose run tripped (the SEW's light rotor, a load taken off near its trip
    speed) printed only "N control periods recorded", exit 0: the user diagnosed half a profile
    without knowing. It now says the fault with the motor file's limit, the load-step hint and
    how far the record goes, exit 4 as `run`; the record is written and loads."""
    prof = tmp_path / "trip.yaml"
    prof.write_text(
        f"name: trip\nmotor: {ROOT}/profiles/motors/sew-cm3c80s.yaml\n"
        f"rig: {ROOT}/profiles/rigs/default.yaml\n"
        "segments:\n"
        "  - {name: up, duration_s: 0.25, speed_rpm: 600, ramp_rpm_s: 6000, load_nm: 4.0}\n"
        "  - {name: load off, duration_s: 0.3, speed_rpm: 600, load_nm: 0}\n"
        "  - {name: stop, duration_s: 0.2, speed_rpm: 0, ramp_rpm_s: 6000, load_nm: 0}\n"
    )
    out = tmp_path / "r.mcap"
    assert main(["gap", "record", str(prof), "-o", str(out)]) == 4
    io = capsys.readouterr()
    n = int(re.match(rf"{re.escape(str(out))}: (\d+) control periods recorded", io.out).group(1))
    assert "device faulted (over_speed: beyond speed_trip_rpm 720 r/min" in io.err
    t_end = float(
        re.search(
            r"the record holds the run up to ([\d.]+) s of the profile's 0.75 s", io.err
        ).group(1)
    )
    assert 0.25 < t_end < 0.3 and abs(n * 50e-6 - t_end) < 1e-3
    assert "hint: the fault came" in io.err and "'load off'" in io.err
    rec = load_record(out)
    assert isinstance(rec, ControlRecord) and rec.n == n


def test_the_sew_diagnosis_profile_runs_to_its_end_on_its_rig(tmp_path, capsys):
    """`gap record diagnose-sew` (the diagnosis excitation scaled to the SEW CM3C80S, on its
    measured map): every period of the profile recorded, no fault, with every current and speed
    level the diagnosis needs (both directions, loaded and not)."""
    out = tmp_path / "sew.mcap"
    assert main(["gap", "record", "diagnose-sew", "--seed", "2", "-o", str(out)]) == 0
    io = capsys.readouterr()
    assert "fault" not in io.err, io.err
    rec = load_record(out)
    assert isinstance(rec, ControlRecord) and abs(rec.n * rec.ts_s - 4.1) < 1e-3
    speed_rpm = rec.omega_e_rad_s / 4 * 60 / (2 * np.pi)
    assert speed_rpm.max() > 440 and speed_rpm.min() < -440
    i_peak = np.abs(rec.i_abc).max()
    assert 8.0 < i_peak < 20.0  # loaded (up to 5 N m) and inside the bench's +-20 A sensors
