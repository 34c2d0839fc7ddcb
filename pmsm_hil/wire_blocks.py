"""Device frames' payloads to log messages in bulk (the run's recorder, pmsm_hil.recorder): the
payloads of many frames of one message, joined, decoded as one numpy array and converted to the
CDR layout of the message's topic with the very operations of the decoder
(pmsm_hil.protocol.codec: the wire value as a float64 times its scale) and of the writer (the
field's CDR type), so that the octets are those of the frame handlers' ``LogWriter.write``
(tests/test_recorder.py)."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from pmsm_hil.log.blocks import CDR_HEADER
from pmsm_hil.protocol import generated as gen

__all__ = ["block_encoder", "wire_dtype"]


def wire_dtype(msg: str) -> np.dtype:
    """The payload of device message ``msg`` as a numpy record: its fields at their octets
    (little-endian, unpadded), an array field as a sub-array."""
    spec = gen.BY_NAME[msg]
    names, formats, offsets, at = [], [], [], 0
    for f in spec.fields:
        code, size = gen.WIRE_TYPES[f.type][:2]
        names.append(f.name)
        formats.append(np.dtype("<" + code) if f.count == 1 else (np.dtype("<" + code), f.count))
        offsets.append(at)
        at += size * f.count
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": at})


def _float64_run(dtype: np.dtype, names: tuple[str, ...]) -> int | None:
    """The offset of ``names`` in ``dtype`` when they are float64 fields one after the other."""
    first = dtype.fields[names[0]][1]  # type: ignore[index]
    for k, n in enumerate(names):
        ft, off = dtype.fields[n][:2]  # type: ignore[index]
        if ft != np.dtype("<f8") or off != first + 8 * k:
            return None
    return first


def block_encoder(
    msg: str,
    ts_s: float,
    names: tuple[str, ...],
    dtype: np.dtype,
    template: bytes | None = None,
    bits: Mapping[str, tuple[str, int]] | None = None,
) -> Callable[[bytes], tuple[np.ndarray, np.ndarray]] | None:
    """Payload octets of many ``msg`` frames (joined) -> (t_s, the CDR data of their log
    messages as ``dtype``, the topic's layout). ``names``: the log fields, ``t_s`` first;
    ``template``: the data's octets before the fields are filled in (a layout with strings,
    ``LogWriter.fixed_layout``; by default the encapsulation header and zeros); ``bits``: log
    fields that are a bit of a message field (name -> (field, mask)), as booleans. None when a log
    field is neither a scalar field of the message nor such a bit.

    When the log fields after ``t_s`` are float64 one after the other (telemetry), they are cast
    in one conversion and the scaled ones multiplied by their scales in one; otherwise field by
    field."""
    spec = gen.BY_NAME[msg]
    scales = {f.name: f.scale for f in spec.fields if f.count == 1}
    bits = dict(bits or {})
    fields = list(names[1:])
    if "tick" not in scales or any(n not in scales and n not in bits for n in fields):
        return None
    if any(src not in scales for src, _mask in bits.values()):
        return None
    if template is not None and len(template) != dtype.itemsize:
        return None
    tpl = np.frombuffer(template, np.uint8) if template is not None else None
    wire = wire_dtype(msg)
    size = dtype.itemsize
    t_at = dtype.fields["t_s"][1]  # type: ignore[index]
    run_at = _float64_run(dtype, tuple(fields))
    as_f8 = np.dtype({"names": fields, "formats": ["<f8"] * len(fields)})
    scaled = np.array(
        [k for k, n in enumerate(fields) if n not in bits and scales[n] is not None], dtype=np.intp
    )
    factors = np.array([scales[fields[k]] for k in scaled], dtype=np.float64)

    def encode(payloads: bytes) -> tuple[np.ndarray, np.ndarray]:
        v = np.frombuffer(payloads, dtype=wire)
        n = len(v)
        if tpl is None:
            raw = np.zeros((n, size), dtype=np.uint8)
            raw[:, :4] = CDR_HEADER
        else:
            raw = np.empty((n, size), dtype=np.uint8)
            raw[:] = tpl
        t = v["tick"] * ts_s
        raw[:, t_at : t_at + 8].view("<f8")[:, 0] = t
        out = raw.view(dtype).reshape(n)
        if run_at is None:
            for name in fields:
                if name in bits:
                    src, mask = bits[name]
                    out[name] = (v[src] & mask) != 0
                    continue
                sc = scales[name]
                out[name] = v[name] if sc is None else v[name] * sc
            return t, out
        vals = v[fields].astype(as_f8).view("<f8").reshape(n, len(fields))
        if len(scaled):
            vals[:, scaled] *= factors
        raw[:, run_at : run_at + 8 * len(fields)].view("<f8")[:] = vals
        return t, out

    return encode
