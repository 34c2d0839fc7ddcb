"""The wire protocol (docs/protocol.md) and its CAN mapping (docs/can.md)."""

from __future__ import annotations

from pathlib import Path

DBC_NAME = "pmsm_proto.dbc"


def dbc_path() -> Path:
    """The CAN database of the protocol (identifiers for the default node 1, docs/can.md): the
    installed package data `pmsm_hil.proto`, or the source tree's firmware/proto."""
    from pmsm_hil.profiles.shipped import package_dir

    installed = package_dir("pmsm_hil.proto")
    if installed is not None and (installed / DBC_NAME).is_file():
        return installed / DBC_NAME
    return Path(__file__).resolve().parents[2] / "firmware" / "proto" / DBC_NAME


__all__ = ["dbc_path"]
