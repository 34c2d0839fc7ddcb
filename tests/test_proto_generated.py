"""CI check: the generated protocol files and golden frames in the tree are what the generators make.

Regenerates into a temporary directory and compares byte for byte; on failure, run
`python3 -m tools.gen_proto && python3 -m tools.gen_golden` from the repository root.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

OUTPUTS = {
    "tools.gen_proto": [
        "firmware/core/proto_gen.h",
        "firmware/core/proto_gen.c",
        "pmsm_hil/protocol/generated.py",
        "docs/protocol.md",
        "firmware/core/proto_can_gen.h",
        "firmware/core/proto_can_gen.c",
        "pmsm_hil/protocol/can_generated.py",
        "firmware/proto/pmsm_proto.dbc",
        "docs/can.md",
    ],
    "tools.gen_golden": ["tests/data/golden_frames.json", "firmware/tests/golden_frames.h"],
}


@pytest.mark.parametrize("module", sorted(OUTPUTS))
def test_generated_files_are_up_to_date(module, tmp_path):
    subprocess.run([sys.executable, "-m", module, "--out-dir", str(tmp_path)], cwd=ROOT, check=True)
    for rel in OUTPUTS[module]:
        fresh = (tmp_path / rel).read_text(encoding="utf-8")
        committed = (ROOT / rel).read_text(encoding="utf-8")
        assert committed == fresh, (
            f"{rel} is stale: run `python3 -m {module}` from the repository root"
        )


def test_generation_is_deterministic(tmp_path):
    for run in ("a", "b"):
        subprocess.run(
            [sys.executable, "-m", "tools.gen_proto", "--out-dir", str(tmp_path / run)],
            cwd=ROOT,
            check=True,
        )
    for rel in OUTPUTS["tools.gen_proto"]:
        assert (tmp_path / "a" / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes()


def test_schema_errors_are_clear(tmp_path):
    sys.path.insert(0, str(ROOT))
    try:
        from tools import gen_proto
    finally:
        sys.path.remove(str(ROOT))
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "protocol_version: 1\nenums: {}\nmessages:\n"
        "  a: {id: 1, dir: h2d, fields: [{name: x, type: u64}]}\n"
    )
    with pytest.raises(
        gen_proto.SchemaError, match=r"message 'a' field 'x': type 'u64' is not one of"
    ):
        gen_proto.load_schema(bad)
    bad.write_text(
        "protocol_version: 1\nenums: {}\nmessages:\n"
        "  a: {id: 1, dir: h2d, fields: []}\n  b: {id: 1, dir: d2h, fields: []}\n"
    )
    with pytest.raises(gen_proto.SchemaError, match="messages 'a' and 'b' share id 0x01"):
        gen_proto.load_schema(bad)
