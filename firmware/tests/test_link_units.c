/* Unit tests of the link and run bookkeeping in core/: txq (UART ring), can_link (CAN frames of
 * docs/can.md, built here by hand from the written rules), profile_exec (segments, ramp, end)
 * and capture (pre-trigger, post-fill, freeze, order). */
#include "check.h"

#include <string.h>

#include "txq.h"
#include "can_link.h"
#include "frame.h"
#include "profile_exec.h"
#include "capture.h"

/* ------------------------------------------------------------------ txq */

static void test_txq(void)
{
    static txq_t q;
    uint16_t a[700], out[1024], i, n, o = 0u;
    bool ok;
    txq_init(&q);
    CHECK(txq_free(&q) == TXQ_SIZE, "txq: empty has all octets free");
    for (i = 0u; i < 700u; i++) {
        a[i] = (uint16_t)(i & 0xFFu);
    }
    CHECK(txq_push(&q, a, 700u), "txq: 700 octets fit");
    CHECK(!txq_push(&q, a, 400u), "txq: 400 more do not fit (whole frames or nothing)");
    CHECK(q.dropped == 1u && q.level == 700u,
          "txq: the refused frame is counted, the queue unchanged");
    n = txq_pop_n(&q, out, 500u);
    CHECK(n == 500u && out[0] == 0u && out[499] == (499u & 0xFFu),
          "txq: pop_n gives the oldest first");
    CHECK(txq_push(&q, a, 600u), "txq: after draining, 600 fit (wrapping round the ring)");
    n = txq_pop_n(&q, out, 1024u);
    CHECK(n == 800u, "txq: pop_n stops at the level");
    ok = true;
    for (i = 0u; i < 200u; i++) {
        ok = ok && out[i] == (uint16_t)((500u + i) & 0xFFu);
    }
    for (i = 0u; i < 600u; i++) {
        ok = ok && out[200u + i] == (uint16_t)(i & 0xFFu);
    }
    CHECK(ok, "txq: order kept across the wrap");
    CHECK(!txq_pop(&q, &o) && q.level == 0u, "txq: pop on empty returns false");
}

/* ------------------------------------------------------------------ can_link */

static uint16_t can_id(uint16_t func, uint16_t node)
{
    return (uint16_t)((func << PROTO_CAN_NODE_BITS) | node);
}

static void test_can_tx_direct(void)
{
    static can_link_t c;
    proto_telem_fast_t t;
    proto_can_layout_t l;
    uint16_t payload[PROTO_MAX_PAYLOAD], got[PROTO_MAX_PAYLOAD + 8u], n, k, i, m = 0u, crc = 0u;
    uint16_t crc_in[PROTO_MAX_PAYLOAD + 2u];
    can_frame_t fr;
    bool ids_ok = true;
    memset(&t, 0, sizeof t);
    t.tick = 123456u;
    t.speed_rpm = 1000.0f;
    t.i_q_a = 3.5f;
    n = proto_telem_fast_pack(&t, payload);
    CHECK(proto_can_layout(PROTO_ID_TELEM_FAST, &l) && !l.transfer && !l.h2d,
          "can: telem_fast is a direct d2h message");
    can_link_init(&c, 5u);
    CHECK(can_link_send(&c, PROTO_ID_TELEM_FAST, 0x42u, payload, n), "can: direct send queued");
    CHECK(can_link_tx_level(&c) == l.n_frames, "can: one frame per layout frame");
    CHECK(l.n_frames >= 2u && l.crc_frame < l.n_frames, "can: telem_fast carries a CRC");
    for (k = 0u; k < l.n_frames; k++) {
        uint16_t end = (uint16_t)(k == l.crc_frame ? l.len[k] - PROTO_CAN_CRC_OCTETS : l.len[k]);
        CHECK(can_link_tx_pop(&c, &fr), "can: frame pops");
        ids_ok = ids_ok && fr.id == can_id((uint16_t)(l.func + k), 5u) && fr.dlc == l.len[k];
        for (i = (k == 0u) ? 1u : 0u; i < end; i++) {
            got[m++] = fr.data[i];
        }
        if (k == l.crc_frame) {
            crc = (uint16_t)((fr.data[end] << 8) | fr.data[end + 1u]);
        }
        if (k == 0u) {
            CHECK(fr.data[0] == 0x42u, "can: frame 0 starts with the seq octet");
        }
    }
    CHECK(ids_ok, "can: identifiers function + k << 4 | node, lengths of the layout");
    CHECK(m == n && memcmp(got, payload, n * sizeof(uint16_t)) == 0,
          "can: the frames carry the payload in order");
    crc_in[0] = PROTO_ID_TELEM_FAST;
    crc_in[1] = 0x42u;
    memcpy(&crc_in[2], payload, n * sizeof(uint16_t));
    CHECK(crc == frame_crc16(crc_in, (uint16_t)(n + 2u)),
          "can: the CRC frame ends with the CRC-16 over msg_id, seq, payload");
    CHECK(can_link_tx_peek(&c) == 0, "can: queue empty afterwards");
}

static void test_can_tx_transfer_and_full(void)
{
    static can_link_t c;
    static proto_capture_chunk_t cc;
    proto_can_layout_t l;
    uint16_t payload[PROTO_MAX_PAYLOAD], crc_in[PROTO_MAX_PAYLOAD + 2u], n, crc, sent = 0u;
    can_frame_t fr;
    memset(&cc, 0, sizeof cc);
    cc.offset = 8u;
    cc.n_valid = 8u;
    cc.i_a_a[3] = 1.5f;
    n = proto_capture_chunk_pack(&cc, payload);
    CHECK(proto_can_layout(PROTO_ID_CAPTURE_CHUNK, &l) && l.transfer,
          "can: capture_chunk goes by transfer");
    can_link_init(&c, 1u);
    CHECK(can_link_send(&c, PROTO_ID_CAPTURE_CHUNK, 7u, payload, n), "can: transfer queued");
    CHECK(can_link_tx_pop(&c, &fr), "can: header frame");
    crc_in[0] = PROTO_ID_CAPTURE_CHUNK;
    crc_in[1] = 7u;
    memcpy(&crc_in[2], payload, n * sizeof(uint16_t));
    crc = frame_crc16(crc_in, (uint16_t)(n + 2u));
    CHECK(
        fr.id == can_id(PROTO_CAN_FUNC_TRANSFER_D2H, 1u) && fr.dlc == PROTO_CAN_TRANSFER_HEADER &&
            fr.data[0] == 0u && fr.data[1] == PROTO_ID_CAPTURE_CHUNK && fr.data[2] == 7u &&
            fr.data[3] == n && fr.data[4] == (crc >> 8) && fr.data[5] == (crc & 0xFFu),
        "can: header [0, msg_id, seq, len, crc_hi, crc_lo] with the CRC over msg_id, seq, payload");
    CHECK(can_link_tx_pop(&c, &fr) && fr.data[0] == 1u && fr.dlc == 1u + PROTO_CAN_TRANSFER_DATA &&
              fr.data[1] == payload[0],
          "can: data frame 1 carries index 1 and the first 7 octets");
    can_link_init(&c, 1u);
    while (can_link_send(&c, PROTO_ID_CAPTURE_CHUNK, 0u, payload, n)) {
        sent++;
    }
    CHECK(sent >= 1u && can_link_tx_level(&c) <= CAN_TXQ_FRAMES,
          "can: a full queue refuses whole messages");
}

/* host-side frames of an h2d direct message, by the rules of docs/can.md */
static uint16_t h2d_frames(uint16_t msg_id, uint16_t seq, const uint16_t *payload, uint16_t n,
                           can_frame_t *fr, uint16_t node)
{
    proto_can_layout_t l;
    uint16_t k, i, p = 0u, crc_in[PROTO_MAX_PAYLOAD + 2u], crc;
    (void)proto_can_layout(msg_id, &l);
    crc_in[0] = msg_id;
    crc_in[1] = seq;
    memcpy(&crc_in[2], payload, n * sizeof(uint16_t));
    crc = frame_crc16(crc_in, (uint16_t)(n + 2u));
    for (k = 0u; k < l.n_frames; k++) {
        uint16_t end = (uint16_t)(k == l.crc_frame ? l.len[k] - PROTO_CAN_CRC_OCTETS : l.len[k]);
        fr[k].id = can_id((uint16_t)(l.func + k), node);
        fr[k].dlc = l.len[k];
        for (i = 0u; i < end; i++) {
            fr[k].data[i] = (k == 0u && i == 0u) ? seq : payload[p++];
        }
        if (k == l.crc_frame) {
            fr[k].data[end] = (uint16_t)(crc >> 8);
            fr[k].data[end + 1u] = (uint16_t)(crc & 0xFFu);
        }
    }
    return l.n_frames;
}

/* host-side frames of an h2d transfer (header, data frames of 7 octets) */
static uint16_t h2d_transfer(uint16_t msg_id, uint16_t seq, const uint16_t *payload, uint16_t n,
                             can_frame_t *fr, uint16_t node, uint16_t crc_xor)
{
    uint16_t crc_in[PROTO_MAX_PAYLOAD + 2u], crc, k = 1u, p = 0u, i;
    crc_in[0] = msg_id;
    crc_in[1] = seq;
    memcpy(&crc_in[2], payload, n * sizeof(uint16_t));
    crc = (uint16_t)(frame_crc16(crc_in, (uint16_t)(n + 2u)) ^ crc_xor);
    fr[0].id = can_id(PROTO_CAN_FUNC_TRANSFER_H2D, node);
    fr[0].dlc = PROTO_CAN_TRANSFER_HEADER;
    fr[0].data[0] = 0u;
    fr[0].data[1] = msg_id;
    fr[0].data[2] = seq;
    fr[0].data[3] = n;
    fr[0].data[4] = (uint16_t)(crc >> 8);
    fr[0].data[5] = (uint16_t)(crc & 0xFFu);
    while (p < n) {
        fr[k].id = fr[0].id;
        fr[k].data[0] = k;
        for (i = 0u; i < PROTO_CAN_TRANSFER_DATA && p < n; i++) {
            fr[k].data[1u + i] = payload[p++];
        }
        fr[k].dlc = (uint16_t)(1u + i);
        k++;
    }
    return k;
}

/* Frames of two messages joined after a lost burst (head of one, tail of the next) pass every
 * order check; the end-to-end CRC must reject them, count them and deliver nothing. */
static void test_can_rx_splice(can_link_t *c, const uint16_t *payload_a, uint16_t n)
{
    proto_sim_plant_t sp;
    can_frame_t a[PROTO_CAN_MAX_FRAMES], b[PROTO_CAN_MAX_FRAMES];
    uint16_t payload_b[PROTO_MAX_PAYLOAD], nf, k;
    uint32_t crc_before = c->err_crc, ok_before = c->msgs_ok;
    int16_t r = CAN_RX_NONE;
    sp.index = 4u;
    sp.r_s_scale = 1.0f;
    sp.psi_f_scale = 0.5f;
    (void)proto_sim_plant_pack(&sp, payload_b);
    nf = h2d_frames(PROTO_ID_SIM_PLANT, 20u, payload_a, n, a, 3u);
    (void)h2d_frames(PROTO_ID_SIM_PLANT, 21u, payload_b, n, b, 3u);
    for (k = 0u; k < nf; k++) { /* head of A, the rest of A and the head of B lost, tail of B */
        const can_frame_t *f = k == 0u ? &a[0] : &b[k];
        r = can_link_rx(c, f->id, f->data, f->dlc);
    }
    CHECK(r == CAN_RX_ERR_CRC && c->err_crc == crc_before + 1u && c->msgs_ok == ok_before,
          "can rx: a spliced message (head of one, tail of the next) is rejected and counted");
    for (k = 0u; k < nf; k++) {
        r = can_link_rx(c, b[k].id, b[k].data, b[k].dlc);
    }
    CHECK(r == CAN_RX_MSG && c->seq == 21u, "can rx: the next whole message passes");
    b[nf - 1u].data[0] ^= 0x04u; /* one flipped bit that the frame CRC would have caught */
    for (k = 0u; k < nf; k++) {
        r = can_link_rx(c, b[k].id, b[k].data, b[k].dlc);
    }
    CHECK(r == CAN_RX_ERR_CRC, "can rx: a changed octet fails the end-to-end CRC");
}

static void test_can_rx(void)
{
    static can_link_t c;
    proto_sim_plant_t sp;
    proto_config_motor_t m;
    proto_can_layout_t l;
    can_frame_t fr[40];
    uint16_t payload[PROTO_MAX_PAYLOAD], n, nf, k;
    int16_t r = CAN_RX_NONE;
    uint32_t crc_before;
    bool none_before = true;
    sp.index = 3u;
    sp.r_s_scale = 1.25f;
    sp.psi_f_scale = 0.9f;
    n = proto_sim_plant_pack(&sp, payload);
    CHECK(proto_can_layout(PROTO_ID_SIM_PLANT, &l) && !l.transfer && l.h2d && l.n_frames >= 2u,
          "can rx: sim_plant is a direct h2d message of several frames");
    nf = h2d_frames(PROTO_ID_SIM_PLANT, 9u, payload, n, fr, 3u);
    can_link_init(&c, 3u);
    for (k = 0u; k < nf; k++) {
        r = can_link_rx(&c, fr[k].id, fr[k].data, fr[k].dlc);
        none_before = none_before && (k + 1u == nf || r == CAN_RX_NONE);
    }
    CHECK(none_before, "can rx: nothing complete before the last frame");
    CHECK(r == CAN_RX_MSG && c.msg_id == PROTO_ID_SIM_PLANT && c.seq == 9u && c.payload_len == n &&
              memcmp(c.payload, payload, n * sizeof(uint16_t)) == 0,
          "can rx: a direct message reassembled");
    CHECK(can_link_rx(&c, (uint16_t)((fr[0].id & ~0xFu) | 4u), fr[0].data, fr[0].dlc) ==
              CAN_RX_NONE,
          "can rx: frames for another node are ignored");
    CHECK(can_link_rx(&c, fr[1].id, fr[1].data, fr[1].dlc) == CAN_RX_ERR_ORDER && c.err_order == 1u,
          "can rx: a frame without its first one is out of order");
    CHECK(can_link_rx(&c, fr[0].id, fr[0].data, (uint16_t)(fr[0].dlc - 1u)) == CAN_RX_ERR_LEN,
          "can rx: a frame of the wrong length");
    test_can_rx_splice(&c, payload, n);

    memset(&m, 0, sizeof m);
    m.pole_pairs = 4u;
    m.r_s_ohm = 0.9f;
    m.v_dc_max_v = 750.0f;
    n = proto_config_motor_pack(&m, payload);
    nf = h2d_transfer(PROTO_ID_CONFIG_MOTOR, 17u, payload, n, fr, 3u, 0u);
    for (k = 0u; k < nf; k++) {
        r = can_link_rx(&c, fr[k].id, fr[k].data, fr[k].dlc);
    }
    CHECK(r == CAN_RX_MSG && c.msg_id == PROTO_ID_CONFIG_MOTOR && c.seq == 17u &&
              c.payload_len == n && memcmp(c.payload, payload, n * sizeof(uint16_t)) == 0,
          "can rx: a transfer reassembled, CRC checked");
    crc_before = c.err_crc;
    nf = h2d_transfer(PROTO_ID_CONFIG_MOTOR, 18u, payload, n, fr, 3u, 0x0100u);
    for (k = 0u; k < nf; k++) {
        r = can_link_rx(&c, fr[k].id, fr[k].data, fr[k].dlc);
    }
    CHECK(r == CAN_RX_ERR_CRC && c.err_crc == crc_before + 1u,
          "can rx: a transfer with a bad CRC is rejected and counted");
    nf = h2d_transfer(PROTO_ID_CONFIG_MOTOR, 19u, payload, n, fr, 3u, 0u);
    (void)can_link_rx(&c, fr[0].id, fr[0].data, fr[0].dlc);
    CHECK(can_link_rx(&c, fr[2].id, fr[2].data, fr[2].dlc) == CAN_RX_ERR_ORDER,
          "can rx: a transfer with a missing data frame is dropped");
}

/* ------------------------------------------------------------------ profile_exec */

static void test_profile(void)
{
    static profile_exec_t p;
    profile_segment_t s;
    profile_out_t o;
    uint32_t t, starts = 0u, ticks = 0u;
    float ramp_at_5 = 0.0f;
    memset(&s, 0, sizeof s);
    profile_clear(&p, 2u);
    CHECK(!profile_complete(&p), "profile: incomplete before the segments");
    s.duration_s = 0.01f; /* 10 periods of 1 ms */
    s.speed_rpm = 100.0f;
    s.ramp_rpm_s = 1000.0f; /* 1 r/min per period */
    s.flags = PROFILE_FLAG_CAPTURE;
    CHECK(profile_set(&p, 0u, &s), "profile: segment 0 set");
    CHECK(!profile_set(&p, 2u, &s), "profile: an index past the declared count is refused");
    s.duration_s = 0.005f;
    s.ramp_rpm_s = 0.0f;
    s.speed_rpm = -50.0f;
    s.load_nm = 2.0f;
    s.flags = 0u;
    s.kind = PROFILE_KIND_RUN;
    CHECK(profile_set(&p, 1u, &s) && profile_complete(&p), "profile: complete with both segments");
    s.duration_s = 0.0f;
    CHECK(!profile_set(&p, 1u, &s), "profile: zero duration refused");
    profile_start(&p, 1e-3f);
    for (t = 0u; t < 40u; t++) {
        profile_step(&p, 1e-3f, &o);
        starts += o.segment_started ? 1u : 0u;
        if (t == 0u) {
            CHECK(o.segment_started && o.index == 0u && (o.flags & PROFILE_FLAG_CAPTURE) &&
                      o.seg_ticks == 10u,
                  "profile: the first period starts segment 0 with its flags and length");
        }
        if (t == 4u) {
            ramp_at_5 = o.speed_ref_rpm;
        }
        if (t == 10u) {
            CHECK(o.segment_started && o.index == 1u && o.tick_in_seg == 0u && o.load_nm == 2.0f &&
                      o.speed_ref_rpm == -50.0f,
                  "profile: segment 1 after 10 periods, a step to its speed");
        }
        if (o.finished) {
            ticks = t;
            break;
        }
    }
    CHECK_NEAR(ramp_at_5, 5.0f, 1e-4, "profile: the ramp climbs 1 r/min per period");
    CHECK(starts == 2u && ticks == 15u,
          "profile: finished in the period after the last one (10 + 5)");
    CHECK(o.load_nm == 0.0f && o.speed_ref_rpm == -50.0f,
          "profile: at the end the load goes, the reference holds");
    profile_step(&p, 1e-3f, &o);
    CHECK(!o.finished && !o.segment_started, "profile: finished only once");
}

/* ------------------------------------------------------------------ capture */

static void sample(capture_sample_t *s, uint32_t k)
{
    s->i_a_a = 0.002f * (float)(k % 1000u);
    s->i_b_a = -s->i_a_a;
    s->i_c_a = 0.0f;
    s->s_abc = (uint16_t)(k & 7u);
    s->v_dc_v = 540.0f;
    s->theta_e_rad = 1.0f;
    s->omega_e_rad_s = -100.0f;
}

static void test_capture(void)
{
    static capture_t c;
    capture_sample_t s;
    uint32_t k;
    capture_init(&c, 100u);
    for (k = 0u; k < 2000u; k++) {
        sample(&s, k);
        capture_record(&c, k, &s);
    }
    CHECK(capture_count(&c) == CAPTURE_LEN && capture_tick0(&c) == 2000u - CAPTURE_LEN,
          "capture: armed, the ring holds the last CAPTURE_LEN samples");
    CHECK(capture_trigger(&c) && capture_count(&c) == 100u, "capture: a trigger keeps pre samples");
    CHECK(!capture_trigger(&c), "capture: no second trigger while one runs");
    for (k = 2000u; k < 2000u + CAPTURE_LEN - 101u; k++) {
        sample(&s, k);
        capture_record(&c, k, &s);
    }
    CHECK(!capture_frozen(&c), "capture: one sample short of full");
    sample(&s, k);
    capture_record(&c, k, &s);
    CHECK(capture_frozen(&c) && capture_count(&c) == CAPTURE_LEN, "capture: frozen when full");
    sample(&s, k + 1u);
    capture_record(&c, k + 1u, &s);
    CHECK(capture_tick0(&c) == 1900u,
          "capture: frozen ignores new samples; oldest is 100 before the trigger");
    CHECK(capture_get(&c, 0u, &s) && s.s_abc == (1900u & 7u), "capture: index 0 is the oldest");
    CHECK_NEAR(s.i_a_a, 0.002f * 900.0f, 1e-3, "capture: current kept at the wire's scale");
    CHECK_NEAR(s.omega_e_rad_s, -100.0f, 0.05, "capture: speed kept");
    CHECK(capture_get(&c, 100u, &s) && s.s_abc == (2000u & 7u),
          "capture: index pre is the trigger period");
    CHECK(!capture_get(&c, CAPTURE_LEN, &s), "capture: past the end");
    capture_rearm(&c);
    CHECK(capture_count(&c) == 0u && !capture_frozen(&c), "capture: re-armed and empty");
    sample(&s, 5u);
    capture_record(&c, 5u, &s);
    CHECK(capture_freeze(&c) && capture_count(&c) == 1u && !capture_freeze(&c),
          "capture: a fault freezes what was recorded, once");
}

int main(void)
{
    test_txq();
    test_can_tx_direct();
    test_can_tx_transfer_and_full();
    test_can_rx();
    test_profile();
    test_capture();
    return CHECK_DONE();
}
