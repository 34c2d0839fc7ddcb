"""Generate the wire-protocol code from firmware/proto/pmsm_proto.yaml, the one source of truth.

    python3 -m tools.gen_proto                 rewrite the generated files in the tree
    python3 -m tools.gen_proto --out-dir DIR   write them under DIR instead (same relative paths)
    python3 -m tools.gen_proto --check         exit 1 if a generated file in the tree is stale

Outputs: firmware/core/proto_gen.h, firmware/core/proto_gen.c, pmsm_hil/protocol/generated.py and the
tables between the GENERATED markers in docs/protocol.md; the CAN mapping via tools/gen_proto_can.py. This is the only code that reads the yaml.
The output is deterministic: the same yaml gives the same files, byte for byte.
"""

from __future__ import annotations

import argparse
import struct
import sys
from pathlib import Path

from tools.proto_schema import (  # noqa: F401  (re-exported for the tests and gen_proto_can)
    BANNER,
    C_HEADER,
    C_SOURCE,
    DOC,
    DOC_BEGIN,
    DOC_END,
    FIELD_LINE,
    IDENT,
    LINK_OCTETS_PER_S,
    MAX_COBS_BLOCK,
    MESSAGE_LINE,
    PY_TABLES,
    ROOT,
    WIRE_TYPES,
    YAML_PATH,
    Field,
    Message,
    Schema,
    SchemaError,
    WireType,
    _parse_field,
    _parse_message,
    field_notes,
    load_schema,
    schema_hash,
)

# ------------------------------------------------------------------------------------------- C


def c_float(x: float) -> str:
    """A C float literal that the compiler rounds to the same float32 as Python's struct does."""
    text = repr(float(x))
    return text + "f" if ("." in text or "e" in text) else text + ".0f"


def f32_floor(x: int) -> float:
    """Largest float32 <= x (the saturation threshold for 32-bit integers in float arithmetic)."""
    f = struct.unpack("<f", struct.pack("<f", float(x)))[0]
    while f > x:
        f = struct.unpack(
            "<f", struct.pack("<I", struct.unpack("<I", struct.pack("<f", f))[0] - 1)
        )[0]
    return f


C_LIMITS = {
    "u8": ("0u", "255u"),
    "u16": ("0u", "UINT16_MAX"),
    "u32": ("0u", "UINT32_MAX"),
    "i16": ("INT16_MIN", "INT16_MAX"),
    "i32": ("INT32_MIN", "INT32_MAX"),
}

# helper name -> (C code, helpers it calls)
C_HELPERS: dict[str, tuple[str, tuple[str, ...]]] = {
    "put_u8": (
        "static void put_u8(uint16_t *b, uint16_t v) { b[0] = (uint16_t)(v > 0xFFu ? 0xFFu : v); }",
        (),
    ),
    "put_u16": (
        "static void put_u16(uint16_t *b, uint16_t v)\n{\n"
        "    b[0] = (uint16_t)(v & 0xFFu);\n    b[1] = (uint16_t)((v >> 8) & 0xFFu);\n}",
        (),
    ),
    "put_u32": (
        "static void put_u32(uint16_t *b, uint32_t v)\n{\n"
        "    put_u16(b, (uint16_t)(v & 0xFFFFu));\n    put_u16(b + 2, (uint16_t)(v >> 16));\n}",
        ("put_u16",),
    ),
    "put_i16": (
        "static void put_i16(uint16_t *b, int16_t v) { put_u16(b, (uint16_t)v); }",
        ("put_u16",),
    ),
    "put_i32": (
        "static void put_i32(uint16_t *b, int32_t v) { put_u32(b, (uint32_t)v); }",
        ("put_u32",),
    ),
    "put_f32": (
        "static void put_f32(uint16_t *b, float v)\n{\n"
        "    union { float f; uint32_t u; } bits;  /* IEEE-754 single on the C28x and the host */\n"
        "    bits.f = v;\n    put_u32(b, bits.u);\n}",
        ("put_u32",),
    ),
    "get_u8": (
        "static uint16_t get_u8(const uint16_t *b) { return (uint16_t)(b[0] & 0xFFu); }",
        (),
    ),
    "get_u16": (
        "static uint16_t get_u16(const uint16_t *b)\n{\n"
        "    return (uint16_t)((b[0] & 0xFFu) | ((b[1] & 0xFFu) << 8));\n}",
        (),
    ),
    "get_u32": (
        "static uint32_t get_u32(const uint16_t *b)\n{\n"
        "    return (uint32_t)get_u16(b) | ((uint32_t)get_u16(b + 2) << 16);\n}",
        ("get_u16",),
    ),
    "get_i16": (
        "static int16_t get_i16(const uint16_t *b) { return (int16_t)get_u16(b); }",
        ("get_u16",),
    ),
    "get_i32": (
        "static int32_t get_i32(const uint16_t *b) { return (int32_t)get_u32(b); }",
        ("get_u32",),
    ),
    "get_f32": (
        "static float get_f32(const uint16_t *b)\n{\n"
        "    union { float f; uint32_t u; } bits;\n    bits.u = get_u32(b);\n    return bits.f;\n}",
        ("get_u32",),
    ),
}
for _t in ("u8", "u16", "u32", "i16", "i32"):
    _wt = WIRE_TYPES[_t]
    _ret = "uint16_t" if _t == "u8" else _wt.c_type
    _lo, _hi = C_LIMITS[_t]
    C_HELPERS[f"sat_{_t}"] = (
        f"/* Round half up and saturate to the {_t} range; NaN gives 0. */\n"
        f"static {_ret} sat_{_t}(float x)\n{{\n"
        f"    if (x != x) {{ return 0; }}\n"
        f"    if (x >= {c_float(f32_floor(_wt.hi))}) {{ return {_hi}; }}\n"
        f"    if (x <= {c_float(_wt.lo)}) {{ return {_lo}; }}\n"
        f"    return ({_ret})floorf(x + 0.5f);\n}}",
        (),
    )
HELPER_ORDER = [
    f"{p}_{t}" for p in ("put", "get", "sat") for t in ("u8", "u16", "u32", "i16", "i32", "f32")
]


def c_struct_type(f: Field) -> str:
    return "float" if f.scale is not None else f.type.c_type


def c_field_comment(f: Field) -> str:
    text = f.type.name + (f"[{f.count}]" if f.count > 1 else "")
    if f.scale is not None:
        lo, hi = f.type.lo * f.scale, f.type.hi * f.scale
        text += f" x {f.scale:.10g} on the wire, {lo:.6g} .. {hi:.6g}"
    return text + (f"; {f.note}" if f.note else "")


def render_c_header(s: Schema) -> str:
    out = [
        f"/* Wire protocol: {BANNER}.",
        " *",
        " * pack:   writes the payload octets (one per uint16_t, little-endian), returns PROTO_LEN_x.",
        " *         Scaled fields are SI floats: wire = floor(value / scale + 0.5), saturated, NaN -> 0.",
        " * unpack: false when len != PROTO_LEN_x. */",
        "#ifndef PROTO_GEN_H",
        "#define PROTO_GEN_H",
        "",
        "#include <stdint.h>",
        "#include <stdbool.h>",
        "",
        f"#define PROTO_VERSION {s.version}u",
        f"#define PROTO_SCHEMA_HASH 0x{s.hash:08X}UL  /* CRC-32 of the canonical yaml */",
        f"#define PROTO_MAX_PAYLOAD {s.max_payload}u  /* octets */",
        f"#define PROTO_MSG_COUNT {len(s.messages)}u",
        "",
    ]
    for ename, values in s.enums.items():
        out.append(f"/* enum {ename} */")
        out += [f"#define PROTO_{ename.upper()}_{v.upper()} {n}u" for v, n in values.items()]
        out.append("")
    for m in s.messages:
        direction = "host -> device" if m.dir == "h2d" else "device -> host"
        out.append(f"/* {m.name}: 0x{m.id:02X}, {direction}{', emulator only' if m.sim else ''} */")
        out.append(f"#define PROTO_ID_{m.upper} 0x{m.id:02X}u")
        out.append(f"#define PROTO_LEN_{m.upper} {m.length}u")
        out.append("typedef struct {")
        if not m.fields:
            out.append("    uint16_t unused;  /* no fields */")
        for f in m.fields:
            decl = f"{c_struct_type(f)} {f.name}" + (f"[{f.count}]" if f.count > 1 else "") + ";"
            out.append(f"    {decl:<30} /* {c_field_comment(f)} */")
        out.append(f"}} proto_{m.name}_t;")
        out.append(f"uint16_t proto_{m.name}_pack(const proto_{m.name}_t *m, uint16_t *buf);")
        out.append(
            f"bool proto_{m.name}_unpack(proto_{m.name}_t *m, const uint16_t *buf, uint16_t len);"
        )
        out.append("")
    out += [
        "/* Payload octets of a message id, or -1 for an unknown id. */",
        "int16_t proto_payload_len(uint16_t msg_id);",
        "",
        "#endif",
        "",
    ]
    return "\n".join(out)


def _c_index(f: Field) -> str:
    """Octet index of element i of an array field."""
    step = "i" if f.type.octets == 1 else f"{f.type.octets}u * i"
    return f"{f.offset}u + {step}"


def _c_pack_stmt(f: Field, helpers: set[str]) -> str:
    t = f.type.name
    value = f"m->{f.name}" + ("[i]" if f.count > 1 else "")
    if f.scale is not None:
        helpers.add(f"sat_{t}")
        value = f"sat_{t}({value} * {c_float(1.0 / f.scale)})"
    helpers.add(f"put_{t}")
    if f.count == 1:
        return f"    put_{t}(&buf[{f.offset}], {value});"
    return (
        f"    for (i = 0u; i < {f.count}u; i++) {{\n"
        f"        put_{t}(&buf[{_c_index(f)}], {value});\n    }}"
    )


def _c_unpack_stmt(f: Field, helpers: set[str]) -> str:
    t = f.type.name
    helpers.add(f"get_{t}")
    idx = "[i]" if f.count > 1 else ""
    at = f"&buf[{f.offset}]" if f.count == 1 else f"&buf[{_c_index(f)}]"
    value = f"get_{t}({at})"
    if f.scale is not None:
        value = f"(float){value} * {c_float(f.scale)}"
    stmt = f"m->{f.name}{idx} = {value};"
    if f.count == 1:
        return "    " + stmt
    return f"    for (i = 0u; i < {f.count}u; i++) {{\n        {stmt}\n    }}"


def render_c_source(s: Schema) -> str:
    helpers: set[str] = set()
    bodies = []
    for m in s.messages:
        has_array = any(f.count > 1 for f in m.fields)
        loop_var = ["    uint16_t i;"] if has_array else []
        pack = [
            f"uint16_t proto_{m.name}_pack(const proto_{m.name}_t *m, uint16_t *buf)",
            "{",
            *loop_var,
        ]
        unpack = [
            f"bool proto_{m.name}_unpack(proto_{m.name}_t *m, const uint16_t *buf, uint16_t len)",
            "{",
            *loop_var,
        ]
        if not m.fields:
            pack.append("    (void)m;\n    (void)buf;")
            unpack.append("    (void)m;\n    (void)buf;")
        unpack.append(f"    if (len != PROTO_LEN_{m.upper}) {{\n        return false;\n    }}")
        pack += [_c_pack_stmt(f, helpers) for f in m.fields]
        unpack += [_c_unpack_stmt(f, helpers) for f in m.fields]
        pack += [f"    return PROTO_LEN_{m.upper};", "}", ""]
        unpack += ["    return true;", "}", ""]
        bodies += pack + unpack
    # close over helper dependencies
    todo = list(helpers)
    while todo:
        for dep in C_HELPERS[todo.pop()][1]:
            if dep not in helpers:
                helpers.add(dep)
                todo.append(dep)
    out = [
        f"/* Wire protocol pack/unpack: {BANNER}. */",
        '#include "proto_gen.h"',
        "",
        "#include <math.h>",
        "",
    ]
    out += [C_HELPERS[h][0] + "\n" for h in HELPER_ORDER if h in helpers]
    out += bodies
    out += ["int16_t proto_payload_len(uint16_t msg_id)", "{", "    switch (msg_id) {"]
    out += [
        f"    case PROTO_ID_{m.upper}: return (int16_t)PROTO_LEN_{m.upper};" for m in s.messages
    ]
    out += ["    default: return -1;", "    }", "}", ""]
    return "\n".join(out)


# -------------------------------------------------------------------------------------- Python


def render_python(s: Schema) -> str:
    out = [
        f'"""Wire protocol tables: {BANNER}.',
        "",
        "Payload layout: fields in order, little-endian, no padding; see docs/protocol.md.",
        '"""',
        "import struct",
        "from typing import NamedTuple",
        "",
        f"PROTOCOL_VERSION = {s.version}",
        f"SCHEMA_HASH = 0x{s.hash:08X}",
        f"MAX_PAYLOAD = {s.max_payload}  # octets",
        "",
        "# wire type: (struct code, octets, min, max); min/max are None for f32",
        "WIRE_TYPES = {",
    ]
    out += [
        f"    {t.name!r}: ({t.struct_code!r}, {t.octets}, {t.lo}, {t.hi}),"
        for t in WIRE_TYPES.values()
    ]
    out += [
        "}",
        "",
        "",
        "class FieldSpec(NamedTuple):",
        "    name: str",
        "    type: str            # wire type, a key of WIRE_TYPES",
        "    count: int           # array length; 1 for a scalar",
        "    scale: float | None  # SI units per LSB; None: the value goes on the wire as is",
        "    offset: int          # octet offset in the payload",
        "",
        "",
        "class MessageSpec(NamedTuple):",
        "    id: int",
        "    name: str",
        "    dir: str                       # 'h2d' host to device, 'd2h' device to host",
        "    sim: bool                      # sent only by the emulator's sim board",
        "    length: int                    # payload octets",
        "    fields: tuple[FieldSpec, ...]",
        "    struct: struct.Struct          # the payload, arrays expanded in place",
        "",
        "    @property",
        "    def names(self) -> tuple[str, ...]:",
        "        return tuple(f.name for f in self.fields)",
        "",
        "",
        "ENUMS = {",
    ]
    for ename, values in s.enums.items():
        items = [f"{k!r}: {v}," for k, v in values.items()]
        out.append(f"    {ename!r}: {{")
        out += [f"        {item}" for item in items]
        out.append("    },")
    out += ["}", "", "MESSAGES = ("]
    for m in s.messages:
        fmt = "<" + "".join(
            (str(f.count) if f.count > 1 else "") + f.type.struct_code for f in m.fields
        )
        out.append(f"    MessageSpec(0x{m.id:02X}, {m.name!r}, {m.dir!r}, {m.sim}, {m.length}, (")
        for f in m.fields:
            out.append(
                f"        FieldSpec({f.name!r}, {f.type.name!r}, {f.count}, {f.scale!r}, {f.offset}),"
            )
        out.append(f"    ), struct.Struct({fmt!r})),")
    out += [
        ")",
        "",
        "BY_ID = {m.id: m for m in MESSAGES}",
        "BY_NAME = {m.name: m for m in MESSAGES}",
        "",
    ]
    out += [f"ID_{m.upper} = 0x{m.id:02X}" for m in s.messages]
    out.append("")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------- docs


def render_doc_tables(s: Schema) -> str:
    out = [
        DOC_BEGIN,
        "",
        f"Protocol version {s.version}, schema hash `0x{s.hash:08X}`, longest payload "
        f"{s.max_payload} octets.",
        "",
        "| id | message | dir | payload octets | wire octets | alone on 921.6 kbaud (frames/s) |",
        "|---|---|---|---:|---:|---:|",
    ]
    for m in s.messages:
        d = m.dir + (" (sim)" if m.sim else "")
        out.append(
            f"| 0x{m.id:02X} | `{m.name}` | {d} | {m.length} | {m.wire_octets} | "
            f"{LINK_OCTETS_PER_S // m.wire_octets} |"
        )
    out += [
        "",
        "Wire octets = payload + 2 (id, seq) + 2 (CRC) + 1 (COBS code) + 1 (delimiter).",
        "",
    ]
    for m in s.messages:
        out.append(f"**{m.name}** (0x{m.id:02X})" + (": no fields" if not m.fields else ""))
        if not m.fields:
            out.append("")
            continue
        out += [
            "",
            "| offset | field | type | scale | SI range | note |",
            "|---:|---|---|---|---|---|",
        ]
        for f in m.fields:
            t = f.type.name + (f"[{f.count}]" if f.count > 1 else "")
            if f.scale is None:
                scale, rng = "\u2014", "\u2014"
            else:
                scale = f"{f.scale:.10g}"
                rng = f"{f.type.lo * f.scale:.6g} .. {f.type.hi * f.scale:.6g}"
            out.append(f"| {f.offset} | `{f.name}` | {t} | {scale} | {rng} | {f.note} |")
        out.append("")
    out.append("Enums:")
    out.append("")
    for ename, values in s.enums.items():
        out.append(f"- `{ename}`: " + ", ".join(f"{k} = {v}" for k, v in values.items()))
    out += ["", DOC_END]
    return "\n".join(out)


def splice_doc(text: str, tables: str) -> str:
    begin, end = text.find(DOC_BEGIN), text.find(DOC_END)
    if begin < 0 or end < begin:
        raise SchemaError(f"{DOC}: markers {DOC_BEGIN!r} ... {DOC_END!r} not found")
    return text[:begin] + tables + text[end + len(DOC_END) :]


# ---------------------------------------------------------------------------------------- main


def render_all(root: Path) -> dict[str, str]:
    schema = load_schema(root / YAML_PATH)
    files = {
        C_HEADER: render_c_header(schema),
        C_SOURCE: render_c_source(schema),
        PY_TABLES: render_python(schema),
    }
    doc = root / DOC
    if doc.exists():
        files[DOC] = splice_doc(doc.read_text(encoding="utf-8"), render_doc_tables(schema))
    from tools import gen_proto_can  # the CAN mapping: C, Python, DBC, docs/can.md

    try:
        files.update(gen_proto_can.render_all(root, YAML_PATH, schema.messages, WIRE_TYPES, BANNER))
    except gen_proto_can.CanSchemaError as e:
        raise SchemaError(str(e)) from None
    return files


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python3 -m tools.gen_proto", description=__doc__.splitlines()[0]
    )
    ap.add_argument(
        "--out-dir", type=Path, help="write under this directory instead of the repository"
    )
    ap.add_argument(
        "--check", action="store_true", help="exit 1 if a generated file in the tree is stale"
    )
    args = ap.parse_args(argv)
    try:
        files = render_all(ROOT)
    except SchemaError as e:
        print(f"gen_proto: {e}", file=sys.stderr)
        return 2
    if args.check:
        stale = [
            p
            for p, text in files.items()
            if not (ROOT / p).exists() or (ROOT / p).read_text(encoding="utf-8") != text
        ]
        for p in stale:
            print(f"gen_proto: {p} is stale; run python3 -m tools.gen_proto", file=sys.stderr)
        return 1 if stale else 0
    out_dir = args.out_dir or ROOT
    for rel, text in files.items():
        path = out_dir / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8", newline="\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
