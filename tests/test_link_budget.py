"""The link budget of a profile's telemetry (pmsm_hil.profiles.link_budget): its numbers, the
protocol's frame sizes, the overload warning, also for a file refused for other problems."""

from __future__ import annotations

import pytest
import yaml
from test_profiles import GOOD, PAPER_A, ROOT, write

from pmsm_hil.profiles import (
    FRAME_OVERHEAD_OCTETS,
    PAYLOAD_OCTETS,
    ProfileError,
    link_budget,
    load_profile,
)


def test_link_budget_numbers():
    p = load_profile(PAPER_A)
    b = link_budget(p)
    assert b["capacity_octets_s"] == 92160
    s = b["streams"]
    assert s["telem_fast"]["frame_octets"] == 34 and s["telem_fast"]["octets_s"] == 68000
    assert s["params"]["frame_octets"] == 28 and s["params"]["octets_s"] == 2800
    assert s["status"]["frame_octets"] == 31 and s["status"]["octets_s"] == 310
    assert s["sim_truth"]["frame_octets"] == 58 and s["sim_truth"]["octets_s"] == 5800
    assert b["total_octets_s"] == 76910
    assert b["load"] == pytest.approx(76910 / 92160)
    assert b["warning"] is None
    # a rig sends no sim_truth; three estimators triple the params frames
    b2 = link_budget(p, emulator=False, n_estimators=3)
    assert b2["streams"]["sim_truth"]["octets_s"] == 0
    assert b2["total_octets_s"] == 68000 + 3 * 2800 + 310


def test_link_budget_overload_warns(ws):
    p = load_profile(write("x.yaml", GOOD.replace("fast_hz: 2000", "fast_hz: 2500")))
    b = link_budget(p)
    assert b["load"] > 1 and b["total_octets_s"] == 2500 * 34 + 2800 + 310 + 5800
    assert (
        "link overloaded" in b["warning"]
        and "telemetry.fast_hz to 2222.22 Hz or less" in b["warning"]
    )
    assert any("link overloaded" in w for w in p.warnings)


def test_a_file_with_problems_is_also_warned_of_its_overloaded_link(ws):
    """One pass over a broken file finds the link budget too: the overload is listed after the
    problems (a warning, as for a valid file), computed from its own valid sections."""
    text = GOOD.replace("fast_hz: 2000", "fast_hz: 2500")
    broken = text.replace("duration_s: 1.0", "duration_s: 0")
    assert broken != text
    with pytest.raises(ProfileError) as ei:
        load_profile(write("x.yaml", broken))
    e = ei.value
    assert [p.field for p in e.problems] == ["segments[0].duration_s"]
    valid = load_profile(write("y.yaml", text))
    line = next(w for w in valid.warnings if "link overloaded" in w).split(":")[1]
    assert e.warnings == [f"x.yaml:{line}: {link_budget(valid)['warning']}"]
    assert str(e).splitlines()[-1] == "warning: " + e.warnings[0]
    # a problem in the sections the budget reads: no budget of values that are wrong
    for bad in (
        broken.replace("rho: 1.0", "rho: -1"),
        broken.replace("fast_hz: 2500", "fast_hz: 3000\n  params_hz: 30000"),
    ):
        with pytest.raises(ProfileError) as ei:
            load_profile(write("z.yaml", bad))
        assert ei.value.warnings == [] and "warning" not in str(ei.value)
    # nor a file whose link fits
    with pytest.raises(ProfileError) as ei:
        load_profile(write("w.yaml", GOOD.replace("duration_s: 1.0", "duration_s: 0")))
    assert ei.value.warnings == []


def test_payload_sizes_match_the_protocol_source():
    proto = ROOT / "firmware" / "proto" / "pmsm_proto.yaml"
    if not proto.exists():
        pytest.skip("protocol source not present")
    spec = yaml.safe_load(proto.read_text())
    size = {"u8": 1, "i8": 1, "u16": 2, "i16": 2, "u32": 4, "i32": 4, "f32": 4}
    for name, octets in PAYLOAD_OCTETS.items():
        fields = spec["messages"][name]["fields"]
        assert sum(size[f["type"]] * f.get("count", 1) for f in fields) == octets, name
    assert FRAME_OVERHEAD_OCTETS == 6
