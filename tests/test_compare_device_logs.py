"""tools/compare_device_logs.py: device topics compared bit for bit, host entries left out."""

from __future__ import annotations

import math

from pmsm_hil.log.writer import LogWriter
from tools.compare_device_logs import compare, main


def _log(path, speeds, host_text="started on /dev/pts/0", status_v=540.0):
    with LogWriter(path) as w:
        w.write("/pmsm/events", 0.0, {"kind": "host", "code": 0, "arg": 0, "text": host_text})
        w.write("/pmsm/events", 0.0, {"kind": "started", "code": 8, "arg": 0, "text": "started"})
        for k, v in enumerate(speeds):
            w.write("/pmsm/telemetry", k * 5e-4, {"speed_rpm": v, "i_q_a": 1.5})
        w.write("/pmsm/status", 0.1, {"v_dc_v": status_v})
    return str(path)


def test_identical_device_topics_pass_whatever_the_host_wrote(tmp_path):
    a = _log(tmp_path / "a.mcap", [0.0, 10.0, 20.0])
    b = _log(
        tmp_path / "b.mcap", [0.0, 10.0, 20.0], host_text="started on /dev/pts/7", status_v=1.0
    )
    assert compare(a, b) == []
    assert main([a, b]) == 0


def test_one_ulp_a_signed_zero_or_a_missing_row_is_a_difference(tmp_path, capsys):
    a = _log(tmp_path / "a.mcap", [0.0, 10.0, 20.0])
    ulp = _log(tmp_path / "ulp.mcap", [0.0, math.nextafter(10.0, 11.0), 20.0])
    neg = _log(tmp_path / "neg.mcap", [-0.0, 10.0, 20.0])
    short = _log(tmp_path / "short.mcap", [0.0, 10.0])
    d = compare(a, ulp)
    assert len(d) == 1 and d[0].startswith(
        "/pmsm/telemetry.speed_rpm: 1 of 3 rows differ, first at row 1"
    )
    assert [x.split(":")[0] for x in compare(a, neg)] == ["/pmsm/telemetry.speed_rpm"]
    assert any("shape" in x for x in compare(a, short))
    assert main([a, ulp]) == 1
    assert "speed_rpm" in capsys.readouterr().out
