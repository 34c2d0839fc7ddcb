"""CAN end-to-end check (docs/can.md): a direct message of 2+ frames carries a CRC-16 over msg_id,
seq and payload, so that frames lost in a burst cannot join the head of one message to the tail of
another. Spliced messages are rejected and counted on the host and in the firmware; random burst
loss never yields an accepted message that was not sent."""

from __future__ import annotations

import math
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pmsm_hil.device import inprocess_can_link
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol import can_generated as cg
from pmsm_hil.protocol import codec
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.can_link import CanDecoder, encode_payload_frames
from pmsm_hil.protocol.generated import MESSAGES
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import configure

MULTI = [
    m for m in MESSAGES if not cg.LAYOUTS[m.id].transfer and len(cg.LAYOUTS[m.id].frame_octets) > 1
]
D2H_MULTI = [m for m in MULTI if m.dir == "d2h"]


def _payload(spec, rng: random.Random) -> bytes:
    """A random payload without NaN floats (their bits need not survive a decode)."""
    while True:
        p = bytes(rng.getrandbits(8) for _ in range(spec.length))
        if not any(isinstance(v, float) and math.isnan(v) for v in spec.struct.unpack(p)):
            return p


def test_every_message_of_several_frames_carries_the_check():
    assert {m.name for m in MULTI} >= {"telem_fast", "status", "params", "event", "sim_plant"}
    for m in MULTI:
        lay = cg.LAYOUTS[m.id]
        assert 0 <= lay.crc_frame < len(lay.frame_octets), m.name
        assert sum(lay.frame_octets) == 1 + m.length + cg.CRC_OCTETS, m.name
    singles = [m for m in MESSAGES if not cg.LAYOUTS[m.id].transfer and m not in MULTI]
    assert singles and all(cg.LAYOUTS[m.id].crc_frame == cg.NO_CRC for m in singles)


@pytest.mark.parametrize("spec", D2H_MULTI, ids=lambda s: s.name)
def test_a_spliced_message_is_rejected_by_the_host(spec):
    rng = random.Random(spec.id)
    a = encode_payload_frames(spec.id, 10, _payload(spec, rng))
    b = encode_payload_frames(spec.id, 11, _payload(spec, rng))
    for cut in range(1, len(a)):  # frames cut.. of a and ..cut of b lost
        dec = CanDecoder()
        assert dec.feed(a[:cut] + b[cut:]) == []
        assert dec.crc_errors == 1 and dec.order_errors == 0 and dec.frames_ok == 0
        (fr,) = dec.feed(b)  # the next whole message passes
        assert fr.seq == 11


def test_a_changed_octet_that_keeps_the_layout_is_rejected():
    spec = gen.BY_NAME["telem_fast"]
    frames = encode_payload_frames(spec.id, 3, _payload(spec, random.Random(5)))
    ident, data = frames[2]
    frames[2] = (ident, bytes([data[0] ^ 0x01]) + data[1:])
    dec = CanDecoder()
    assert dec.feed(frames) == [] and dec.crc_errors == 1


def test_a_spliced_message_is_rejected_by_the_firmware(data):
    """sim_plant (h2d, 2 frames): the head of one and the tail of the next, sent to a running
    device. The firmware drops it and counts it in rx_bad, which `status` reports."""
    profile = load_profile(str(data / "short.yaml"))
    settings_ = emulator_settings(
        profile.motor, profile.rig, seed=1, baud=profile.link.baud, ts_s=profile.control.ts_s
    )
    link = inprocess_can_link(settings_)
    session = Session(link)
    session.hello()
    configure(session, profile)
    session.request("start")
    spec = codec.spec_of("sim_plant")
    a = encode_payload_frames(
        spec.id, 40, codec.encode_payload(spec.id, index=0, r_s_scale=1.5, psi_f_scale=1.0)
    )
    b = encode_payload_frames(
        spec.id, 41, codec.encode_payload(spec.id, index=0, r_s_scale=1.0, psi_f_scale=0.5)
    )

    def last_status(polls: int = 20) -> dict:
        got = None
        for _ in range(polls):
            session.send("heartbeat", counter=0)
            for fr in session.poll(0.0):
                if fr.name == "status":
                    got = fr.fields
        assert got is not None
        return got

    before = last_status()["rx_bad"]
    for ident, d in a[:1] + b[1:]:
        link.bus.dev.can_rx(ident, d)
    assert last_status()["rx_bad"] == before + 1
    session.request("stop")


@st.composite
def burst_loss(draw):
    """A stream of random d2h messages (direct of 2+ frames, and capture chunks by transfer) and a
    loss pattern: bursts of 1..12 consecutive frames lost."""
    seed = draw(st.integers(0, 2**32 - 1))
    n_msgs = draw(st.integers(2, 60))
    bursts = draw(st.lists(st.tuples(st.integers(0, 400), st.integers(1, 12)), max_size=8))
    return seed, n_msgs, bursts


SPECS_STREAM = [codec.spec_of("telem_fast"), *D2H_MULTI, codec.spec_of("capture_chunk")]


def run_case(seed: int, n_msgs: int, bursts: list[tuple[int, int]]) -> int:
    """Encode n_msgs random messages, lose the bursts (start frame, length), decode: every message
    out must be one that was sent, whole. Returns the CRC rejections (splices caught)."""
    rng = random.Random(seed)
    sent: dict[tuple[int, int], bytes] = {}
    frames: list[tuple[int, bytes]] = []
    for seq in range(n_msgs):
        # mostly one message type back to back: where a splice passes every order check
        spec = SPECS_STREAM[0] if rng.random() < 0.6 else rng.choice(SPECS_STREAM)
        payload = _payload(spec, rng)
        sent[(spec.id, seq)] = payload
        frames += encode_payload_frames(spec.id, seq, payload)
    lost = set()
    for at, n in bursts:
        lost.update(range(at, at + n))
    kept = [f for i, f in enumerate(frames) if i not in lost]
    dec = CanDecoder()
    for fr in dec.feed(kept):
        want = sent.get((fr.msg_id, fr.seq))
        assert want is not None, (fr.name, fr.seq)
        assert fr.fields == codec.decode_payload(fr.msg_id, want), (fr.name, fr.seq)
    return dec.crc_errors


@settings(
    derandomize=True, max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
@given(burst_loss())
def test_burst_frame_loss_never_yields_a_message_that_was_not_sent(case):
    run_case(*case)


def test_random_burst_loss_forms_splices_and_none_passes():
    """The same property on seeded random patterns, and proof that it is not vacuous: the losses
    joined messages that passed every order check, and only the CRC stopped them."""
    rng = random.Random(2024)
    caught = 0
    for _ in range(200):
        bursts = [(rng.randrange(300), rng.randint(1, 12)) for _ in range(rng.randint(1, 6))]
        caught += run_case(rng.getrandbits(32), 60, bursts)
    assert caught >= 30, caught
