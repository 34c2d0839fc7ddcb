"""Common pydantic base and helpers for the profile, motor and rig models."""

from __future__ import annotations

import hashlib
import math
from typing import Any

from pydantic import BaseModel, ConfigDict, PrivateAttr


class StrictModel(BaseModel):
    """extra='forbid', strict types (no "12" for 12), finite numbers only."""

    model_config = ConfigDict(
        extra="forbid", strict=True, allow_inf_nan=False, validate_default=False
    )


class FileModel(StrictModel):
    """A model read from one YAML file; keeps the path and the text for the log attachments."""

    _path: str = PrivateAttr(default="")
    _yaml_text: str = PrivateAttr(default="")

    @property
    def path(self) -> str:
        """The file's path as it was given (relative paths stay relative)."""
        return self._path

    @property
    def yaml_text(self) -> str:
        """The file's text exactly as read (attached to the MCAP log)."""
        return self._yaml_text

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self._yaml_text.encode("utf-8")).hexdigest()


def num(d: Any, key: str, default: Any = None) -> float | None:
    """``d[key]`` if it is a finite real number (not bool); the default when the key is absent;
    ``None`` when present but not a usable number (pydantic reports that)."""
    if not isinstance(d, dict):
        return None
    if key not in d:
        return default
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def meta_value(v: Any) -> str:
    """Exact text of a value for MCAP metadata (floats round-trip)."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    return str(v)


def default_file(rel: str) -> str:
    """A shipped file by its path in the shipped tree (``rel`` like "rigs/default.yaml")."""
    from .shipped import shipped_file

    return shipped_file(rel)
