"""The wire protocol (docs/protocol.md) and its CAN mapping (docs/can.md)."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

DBC_NAME = "pmsm_proto.dbc"


def dbc_path() -> Path:
    """The CAN database of the protocol (identifiers for the default node 1, docs/can.md): the
    installed package data `pmsm_hil.proto`, or the source tree's firmware/proto."""
    try:
        spec = importlib.util.find_spec("pmsm_hil.proto")
    except ImportError:
        spec = None
    for loc in (spec.submodule_search_locations or []) if spec else []:
        if os.path.isfile(os.path.join(loc, DBC_NAME)):
            return Path(loc) / DBC_NAME
    return Path(__file__).resolve().parents[2] / "firmware" / "proto" / DBC_NAME


__all__ = ["dbc_path"]
