import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture
def root() -> Path:
    return ROOT


@pytest.fixture
def data() -> Path:
    return DATA


@pytest.fixture(autouse=True)
def _chdir_tmp(tmp_path, monkeypatch):
    """Tests run in a temporary folder so that default log paths do not litter the tree."""
    monkeypatch.chdir(tmp_path)
    os.environ.setdefault("COLUMNS", "160")
    yield
