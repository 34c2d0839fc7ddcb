"""Emulator records for the gap tests: a rig of the given effects on top of the sensors the
diagnoser is told about (ADC noise and quantisation, a 2500-line encoder), recorded with `gap
record`'s recorder."""

from __future__ import annotations

from pathlib import Path

import yaml

SENSORS = {
    "adc_noise": {"i_noise_a": 0.02},
    "adc_quantisation": {"adc_lsb_a": 100 / 4096},
    "encoder": {"lines": 2500, "offset_e_rad": 0.0},
}
SPEC = {"i_noise_a": 0.02, "adc_lsb_a": 100 / 4096, "encoder_lines": 2500.0}


def record_rig(
    tmp: Path, name: str, effects: dict, profile: str | Path, seed: int, sensors: bool = True
) -> Path:
    """Record ``profile`` on a rig NAME of ``effects`` (plus the sensors unless ``sensors`` is
    False) into tmp/NAME.mcap; return its path."""
    from pmsm_hil.gapgen.recorder import record_profile

    eff = {k: dict(v) for k, v in SENSORS.items()} if sensors else {}
    for k, v in effects.items():
        eff[k] = dict(eff.get(k, {}), **v)
    rig = tmp / f"{name}.yaml"
    rig.write_text(
        yaml.safe_dump({"name": name, "description": "test", "v_dc_v": None, "effects": eff})
    )
    out = tmp / f"{name}.mcap"
    record_profile(
        profile, out, rig_path=rig, seed=seed, full_log=False, sensors=SPEC if sensors else None
    )
    return out
