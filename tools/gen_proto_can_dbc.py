"""The DBC of the CAN mapping (firmware/proto/pmsm_proto.dbc), built with cantools' database API
from the layouts of tools/gen_proto_can.py: every direct frame with its signals (seq, the fields,
crc_hi/crc_lo in a message's CRC frame) and the two transfer codes as multiplexed messages.

A field whose yaml comment names an enum (`# enum state`, not `# enum fault bits`) gets the
enum's value table (VAL_), as does a transfer header's msg_id, so that a CAN analyser shows
`running` and `config_ctrl` where the host's log shows them."""

from __future__ import annotations

import re

from tools.gen_proto_can import NODE_BITS, TRANSFER_DATA, CanSchema, unit_of


def _signal(name: str, start_octet: int, wt, scale, signed_override=None, choices=None, **kw):
    from cantools.database.can import Signal
    from cantools.database.conversion import BaseConversion

    is_float = wt.name == "f32"
    signed = wt.name.startswith("i") if signed_override is None else signed_override
    k = scale if scale is not None else 1
    conv = BaseConversion.factory(scale=k, offset=0, choices=choices, is_float=is_float)
    if not is_float:  # the physical range the wire type carries (an analyser's [min|max])
        bits = wt.octets * 8
        lo, hi = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
        kw.setdefault("minimum", _tidy(lo * k))
        kw.setdefault("maximum", _tidy(hi * k))
    return Signal(
        name,
        start_octet * 8,
        wt.octets * 8,
        "little_endian",
        signed,
        conversion=conv,
        unit=unit_of(name) or None,
        **kw,
    )


def _tidy(x: float) -> float | int:
    """A range end as written in the DBC: 255, not 255.0; 3276.7, not 3276.7000000000003."""
    x = float(f"{x:.10g}")
    return int(x) if x.is_integer() else x


ENUM_NOTE = re.compile(r"enum (\w+)(?::|$)")  # "enum state", "enum angle_src: ..."; not "... bits"


def choices_of(note: str, enums: dict[str, dict[str, int]]) -> dict[int, str] | None:
    """The value table of a field from its yaml comment, None when it names no (value) enum."""
    m = ENUM_NOTE.match(note or "")
    if m is None or m.group(1) not in enums:
        return None
    return {v: k for k, v in sorted(enums[m.group(1)].items(), key=lambda kv: kv[1])}


def render_dbc(
    s: CanSchema, wire_types: dict, enums: dict[str, dict[str, int]] | None = None
) -> str:
    from cantools.database.can import Database, Message, Node

    u8 = wire_types["u8"]
    host, dev = "host", "device"
    msgs = []
    node = s.node
    for cm in s.messages:
        m = cm.msg
        sender = host if m.dir == "h2d" else dev
        receiver = [dev if m.dir == "h2d" else host]
        if cm.transfer:
            continue
        for k, fields in enumerate(cm.frames):
            sigs, at = [], 0
            if k == 0:
                sigs.append(_signal("seq", 0, u8, None, receivers=receiver))
                at = 1
            for f in fields:
                sigs.append(
                    _signal(
                        f.name,
                        at,
                        f.type,
                        f.scale,
                        receivers=receiver,
                        comment=f.note or None,
                        choices=choices_of(f.note, enums or {}),
                    )
                )
                at += f.octets
            if k == cm.crc_frame:
                for part in ("crc_hi", "crc_lo"):
                    sigs.append(
                        _signal(
                            part,
                            at,
                            u8,
                            None,
                            receivers=receiver,
                            comment="CRC-16/CCITT-FALSE over msg_id, seq, payload",
                        )
                    )
                    at += 1
            name = m.name if cm.n_frames == 1 else f"{m.name}_{k}"
            comment = f"{m.name} (0x{m.id:02X}) frame {k + 1} of {cm.n_frames}"
            msgs.append(
                Message(
                    (cm.func + k) << NODE_BITS | node,
                    name,
                    at,
                    sigs,
                    senders=[sender],
                    comment=comment,
                    strict=True,
                )
            )
    for func, direction, sender, receiver in (
        (s.func_transfer_h2d, "h2d", host, dev),
        (s.func_transfer_d2h, "d2h", dev, host),
    ):
        carried = [cm.msg for cm in s.messages if cm.transfer and cm.msg.dir == direction]
        names = ", ".join(f"{m.name} (0x{m.id:02X})" for m in carried)
        n_data = max(
            (cm.n_frames - 1 for cm in s.messages if cm.transfer and cm.msg.dir == direction),
            default=1,
        )
        sigs = [
            _signal("index", 0, u8, None, is_multiplexer=True, receivers=[receiver]),
            _signal(
                "msg_id",
                1,
                u8,
                None,
                multiplexer_ids=[0],
                multiplexer_signal="index",
                receivers=[receiver],
                choices={m.id: m.name for m in sorted(carried, key=lambda m: m.id)},
            ),
            _signal(
                "seq",
                2,
                u8,
                None,
                multiplexer_ids=[0],
                multiplexer_signal="index",
                receivers=[receiver],
            ),
            _signal(
                "len",
                3,
                u8,
                None,
                multiplexer_ids=[0],
                multiplexer_signal="index",
                receivers=[receiver],
            ),
            _signal(
                "crc_hi",
                4,
                u8,
                None,
                multiplexer_ids=[0],
                multiplexer_signal="index",
                receivers=[receiver],
            ),
            _signal(
                "crc_lo",
                5,
                u8,
                None,
                multiplexer_ids=[0],
                multiplexer_signal="index",
                receivers=[receiver],
            ),
        ]
        from cantools.database.can import Signal

        sigs.append(
            Signal(
                "data",
                8,
                8 * TRANSFER_DATA,
                "little_endian",
                False,
                multiplexer_ids=list(range(1, n_data + 1)),
                multiplexer_signal="index",
                receivers=[receiver],
                comment="7 payload octets (the last frame: fewer, zero-padded)",
            )
        )
        msgs.append(
            Message(
                func << NODE_BITS | node,
                f"transfer_{direction}",
                8,
                sigs,
                senders=[sender],
                comment=f"multi-frame transfer {direction}: {names}",
                strict=True,
            )
        )
    msgs.sort(key=lambda x: x.frame_id)
    db = Database(
        msgs,
        [Node(host, comment="pmsm-hil host"), Node(dev, comment=f"drive, node {node}")],
        version="",
        strict=True,
    )
    return db.as_dbc_string().replace("\r\n", "\n")  # cantools writes CRLF
