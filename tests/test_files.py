"""A user's file written whole or not at all (pmsm_hil.files)."""

from __future__ import annotations

import os

import pytest

from pmsm_hil import files
from pmsm_hil.files import write_text_whole


def test_writes_the_text_and_keeps_the_files_mode(tmp_path):
    p = tmp_path / "motor.yaml"
    write_text_whole(p, "a: 1\n")
    assert p.read_text() == "a: 1\n"
    umask = os.umask(0)
    os.umask(umask)
    assert p.stat().st_mode & 0o777 == 0o666 & ~umask  # as open() would have made it
    p.chmod(0o600)
    write_text_whole(p, "ψ_f: 0.18\n")
    assert p.read_text(encoding="utf-8") == "ψ_f: 0.18\n"
    assert p.stat().st_mode & 0o777 == 0o600
    assert [q.name for q in tmp_path.iterdir()] == ["motor.yaml"]


@pytest.mark.parametrize("error", [KeyboardInterrupt, OSError(28, "No space left on device")])
def test_an_interrupted_write_leaves_the_file_as_it_was(tmp_path, monkeypatch, error):
    p = tmp_path / "motor.yaml"
    p.write_text("commissioned: true\n")

    def fails(*_args):
        raise error

    monkeypatch.setattr(files.os, "replace", fails)
    with pytest.raises(type(error) if isinstance(error, BaseException) else error):
        write_text_whole(p, "cut")
    assert p.read_text() == "commissioned: true\n"
    assert [q.name for q in tmp_path.iterdir()] == ["motor.yaml"]  # no temporary file left


def test_a_folder_that_cannot_be_written_raises_oserror(tmp_path):
    with pytest.raises(OSError):
        write_text_whole(tmp_path / "no-such-folder" / "m.yaml", "x")
