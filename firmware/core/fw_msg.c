/* Messages from the device to the host: acks, the period's events, identify, capture chunks,
 * telemetry. Reads the stages' state; called only by fw.c and fw_cmd.c. */
#include "fw_internal.h"
#include "transforms.h"

#include <math.h>
#include <string.h>

/* ------------------------------------------------------------------ link helpers */

bool fw_send(fw_t *f, uint16_t msg_id, const uint16_t *payload, uint16_t n)
{
    if (f->link.link ==
        FW_LINK_CAN) { /* docs/can.md: whole messages queued as frames, or dropped */
        bool ok = can_link_send(&f->link.can, msg_id, f->link.tx_seq, payload, n);
        f->link.tx_seq = (uint16_t)((f->link.tx_seq + 1u) & 0xFFu);
        f->link.tx.dropped += ok ? 0u : 1u;
        return ok;
    }
    uint16_t len =
        frame_encode(msg_id, f->link.tx_seq, payload, n, f->link.frame_buf,
                     (uint16_t)(sizeof(f->link.frame_buf) / sizeof(f->link.frame_buf[0])));
    f->link.tx_seq = (uint16_t)((f->link.tx_seq + 1u) & 0xFFu);
    if (len == 0u) {
        f->link.tx.dropped++;
        return false;
    }
    return txq_push(&f->link.tx, f->link.frame_buf, len);
}

void fw_send_ack(fw_t *f, uint16_t cmd_id, uint16_t cmd_seq, uint16_t status)
{
    proto_ack_t a;
    uint16_t n;
    a.cmd_id = cmd_id;
    a.cmd_seq = cmd_seq;
    a.status = status;
    n = proto_ack_pack(&a, f->link.payload_buf);
    (void)fw_send(f, PROTO_ID_ACK, f->link.payload_buf, n);
}

static void send_event(fw_t *f, const evq_entry_t *ev)
{
    proto_event_t e;
    uint16_t n;
    e.tick = ev->tick;
    e.code = ev->code;
    e.arg = ev->arg;
    n = proto_event_pack(&e, f->link.payload_buf);
    (void)fw_send(f, PROTO_ID_EVENT, f->link.payload_buf, n);
}

static void send_commission_result(fw_t *f)
{
    proto_commission_result_t r;
    const comm_result_t *c = &f->comm.res;
    uint16_t n, k;
    r.tick =
        f->tick > 0u ? f->tick - 1u : 0u; /* the period that ended the step (flushed after it) */
    r.step = c->step;
    r.status = c->status;
    for (k = 0u; k < COMM_RES_N; k++) {
        r.value[k] = c->value[k];
        r.spread[k] = c->spread[k];
    }
    r.truth_ref[0] = c->ref[0];
    r.truth_ref[1] = c->ref[1];
    n = proto_commission_result_pack(&r, f->link.payload_buf);
    (void)fw_send(f, PROTO_ID_COMMISSION_RESULT, f->link.payload_buf, n);
    memset(&f->comm.res, 0, sizeof(f->comm.res));
    f->comm.result_due = false;
}

void fw_flush(fw_t *f)
{
    uint16_t i;
    if (f->comm.result_due) { /* a commissioning step's result precedes the events it caused */
        send_commission_result(f);
    }
    for (i = 0u; i < evq_count(&f->events); i++) {
        send_event(f, evq_at(&f->events, i));
    }
    evq_clear(&f->events);
    if (f->status_due) {
        f->status_due = false;
        fw_send_status(f);
    }
}

void fw_send_identify(fw_t *f)
{
    proto_identify_t m;
    uint16_t n;
    m.proto_version = PROTO_VERSION;
    m.schema_hash = PROTO_SCHEMA_HASH;
    m.fw_major = FW_VERSION_MAJOR;
    m.fw_minor = FW_VERSION_MINOR;
    m.fw_patch = FW_VERSION_PATCH;
    m.board = f->cfg.board;
    m.tx_buf_octets = TXQ_SIZE;
    m.capture_len = CAPTURE_LEN;
    n = proto_identify_pack(&m, f->link.payload_buf);
    (void)fw_send(f, PROTO_ID_IDENTIFY, f->link.payload_buf, n);
}

void fw_send_capture_chunk(fw_t *f, uint16_t offset)
{
    proto_capture_chunk_t c;
    capture_sample_t s;
    uint16_t i, n, count = capture_count(&f->cap);
    memset(&c, 0, sizeof(c));
    c.offset = offset;
    c.tick0 = capture_tick0(&f->cap);
    n = 0u;
    for (i = 0u; i < 8u; i++) {
        if ((uint32_t)offset + i >= count || !capture_get(&f->cap, (uint16_t)(offset + i), &s)) {
            break;
        }
        c.i_a_a[i] = s.i_a_a;
        c.i_b_a[i] = s.i_b_a;
        c.i_c_a[i] = s.i_c_a;
        c.s_abc[i] = s.s_abc;
        c.v_dc_v[i] = s.v_dc_v;
        c.theta_e_rad[i] = s.theta_e_rad;
        c.omega_e_rad_s[i] = s.omega_e_rad_s;
        n++;
    }
    c.n_valid = n;
    n = proto_capture_chunk_pack(&c, f->link.payload_buf);
    (void)fw_send(f, PROTO_ID_CAPTURE_CHUNK, f->link.payload_buf, n);
}

/* ------------------------------------------------------------------ telemetry */

void fw_send_status(fw_t *f)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    uint16_t n;
    {
        proto_status_t s;
        uint32_t age = (f->isr_count - f->hb_isr);
        float age_ms = (float)age * c->ts_s * 1000.0f;
        s.tick = f->tick;
        s.state = f->state;
        s.segment = f->prof.index;
        s.faults = f->faults;
        s.v_dc_v = f->sig.v_dc_v;
        s.tx_dropped = f->link.tx.dropped;
        s.rx_bad = (uint16_t)(f->link.rx_bad > 0xFFFFu ? 0xFFFFu : f->link.rx_bad);
        s.rx_frames = f->link.rx_frames;
        s.hb_age_ms = (uint16_t)(age_ms > 65535.0f ? 65535.0f : age_ms);
        s.capture_count = capture_count(&f->cap);
        n = proto_status_pack(&s, f->link.payload_buf);
        (void)fw_send(f, PROTO_ID_STATUS, f->link.payload_buf, n);
    }
}

/* Parameter frame of slot 0 (the motor file's values as the predictor sees them) or of estimator
 * slot k (1..IDENT_N_EST). */
void fw_send_params(fw_t *f, uint16_t slot)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    proto_params_t pm;
    uint16_t n;
    const bool nominal_feeds = ident_nominal_feeds(&f->ident);
    pm.tick = f->tick;
    if (slot == 0u) {
        pm.estimator = PROTO_ESTIMATOR_NOMINAL;
        pm.flags = nominal_feeds ? PROTO_PARAMS_FLAG_FEEDS_PREDICTOR : 0u;
        pm.l_d_h = f->motor.l_d_h * c->pred_scale_l_d;
        pm.l_q_h = f->motor.l_q_h * c->pred_scale_l_q;
        pm.psi_f_wb = f->motor.psi_f_wb * c->pred_scale_psi_f;
        pm.r_s_ohm = f->motor.r_s_ohm * c->pred_scale_r_s;
    } else {
        est_out_t o;
        ident_report(&f->ident, (uint16_t)(slot - 1u), &o);
        pm.estimator = slot;
        pm.flags =
            (uint16_t)((o.excited ? PROTO_PARAMS_FLAG_EXCITED : 0u) |
                       (o.converged ? PROTO_PARAMS_FLAG_CONVERGED : 0u) |
                       ((!nominal_feeds && c->predictor == slot) ? PROTO_PARAMS_FLAG_FEEDS_PREDICTOR
                                                                 : 0u));
        pm.l_d_h = o.l_d_h;
        pm.l_q_h = o.l_q_h;
        pm.psi_f_wb = o.psi_f_wb;
        pm.r_s_ohm = o.r_s_ohm;
    }
    n = proto_params_pack(&pm, f->link.payload_buf);
    (void)fw_send(f, PROTO_ID_PARAMS, f->link.payload_buf, n);
}

/* Telemetry streams on staggered phases, so that a control period builds at most one frame with
 * the default rates (fast at phase 0, parameter slots at 1..4, status at 5): the ISR's worst
 * case stays within budget on the F28335 (docs/board-f28335.md). */
#define FW_PHASE_PARAMS 1u
#define FW_PHASE_STATUS (FW_PHASE_PARAMS + IDENT_N_EST + 1u)
#define FW_PHASE_EST    (FW_PHASE_STATUS + 2u)

/* The angle estimator's frame (only when an estimator occupies the angle slot): its identity,
 * lock, confidence, and its errors against the encoder (the truth when one is fitted). */
static void send_est(fw_t *f)
{
    proto_telem_est_t t;
    uint16_t n;
    /* in the loop: its angle is the one the control uses (not an angle_encoder segment, nor the
     * current-frequency start, whose open-loop angle carries the control until the handover) */
    const bool in_loop = !f->seg_angle_encoder && !f->est.open_loop;
    t.tick = f->tick;
    t.estimator = f->ctrl.angle_src;
    t.flags = (uint16_t)((f->est.locked ? PROTO_EST_FLAG_LOCKED : 0u) |
                         (in_loop ? PROTO_EST_FLAG_IN_LOOP : 0u));
    t.confidence = f->est.confidence;
    t.theta_err_rad = tf_wrap_pi(f->est.theta_e_rad - f->enc_out.theta_e_rad);
    t.speed_err_rpm = f->est.speed_rpm - f->enc_out.speed_rpm;
    t.err_signal = f->est.err_rad;
    n = proto_telem_est_pack(&t, f->link.payload_buf);
    (void)fw_send(f, PROTO_ID_TELEM_EST, f->link.payload_buf, n);
}

/* The streams' phases at a run's start (tick 0; the dividers cannot change while a run is active,
 * config_ctrl answers busy), then carried from period to period: no division per period (the
 * C28x has no integer divider, % is a library call of some 100 cycles). */
void fw_tel_start(fw_t *f)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    fw_tel_phase_t *t = &f->tel;
    t->div[FW_TEL_FAST] = c->fast_div;
    t->div[FW_TEL_PARAMS] = c->params_div;
    t->div[FW_TEL_STATUS] = c->status_div;
    t->div[FW_TEL_EST] = c->est_div;
    memset(t->ph, 0, sizeof(t->ph));
    t->u_d_sum_v = 0.0f;
    t->u_q_sum_v = 0.0f;
    t->u_n = 0u;
    t->at[FW_TEL_FAST] = 0u;
    t->at[FW_TEL_PARAMS] = 0u; /* unused: params go out in slots from FW_PHASE_PARAMS */
    t->at[FW_TEL_STATUS] = (uint16_t)(c->status_div != 0u ? FW_PHASE_STATUS % c->status_div : 0u);
    t->at[FW_TEL_EST] = (uint16_t)(c->est_div != 0u ? FW_PHASE_EST % c->est_div : 0u);
}

/* the phases of the next tick (all 0 again where the tick wraps: 2^32 is no multiple of a
 * divider, and tick % div starts again there) */
static void tel_advance(fw_t *f)
{
    fw_tel_phase_t *t = &f->tel;
    uint16_t k;
    for (k = 0u; k < FW_TEL_N; k++) {
        t->ph[k] =
            (uint16_t)(t->ph[k] + 1u >= t->div[k] || f->tick == 0xFFFFFFFFu ? 0u : t->ph[k] + 1u);
    }
}

void fw_send_telemetry(fw_t *f)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    const uint16_t *ph = f->tel.ph;
    fw_tel_phase_t *acc = &f->tel;
    uint16_t n;
    if (c->fast_div != 0u) { /* the voltages' mean over the frame's interval (fw.h) */
        acc->u_d_sum_v += f->sig.u_d_v;
        acc->u_q_sum_v += f->sig.u_q_v;
        acc->u_n++;
    }
    if (c->fast_div != 0u && ph[FW_TEL_FAST] == f->tel.at[FW_TEL_FAST]) {
        proto_telem_fast_t t;
        const float inv_n = 1.0f / (float)acc->u_n;
        t.tick = f->tick;
        t.speed_ref_rpm = f->sig.speed_ref_rpm;
        t.speed_rpm = f->sig.speed_rpm;
        t.speed_est_rpm = f->sig.speed_est_rpm;
        t.theta_e_rad = f->sig.theta_e_rad;
        t.theta_e_est_rad = f->sig.theta_e_est_rad;
        t.i_d_a = f->sig.i_d_a;
        t.i_q_a = f->sig.i_q_a;
        t.i_d_ref_a = f->sig.i_d_ref_a;
        t.i_q_ref_a = f->sig.i_q_ref_a;
        t.u_d_v = acc->u_d_sum_v * inv_n;
        t.u_q_v = acc->u_q_sum_v * inv_n;
        acc->u_d_sum_v = 0.0f;
        acc->u_q_sum_v = 0.0f;
        acc->u_n = 0u;
        t.load_nm = f->sig.load_nm;
        n = proto_telem_fast_pack(&t, f->link.payload_buf);
        (void)fw_send(f, PROTO_ID_TELEM_FAST, f->link.payload_buf, n);
    }
    if (c->params_div != 0u) {
        uint32_t p = ph[FW_TEL_PARAMS];
        uint16_t slots = (uint16_t)(c->identify != 0u ? IDENT_N_EST + 1u : 1u);
        if (p >= FW_PHASE_PARAMS && p < FW_PHASE_PARAMS + slots) {
            fw_send_params(f, (uint16_t)(p - FW_PHASE_PARAMS));
        }
    }
    if (c->status_div != 0u && ph[FW_TEL_STATUS] == f->tel.at[FW_TEL_STATUS]) {
        fw_send_status(f);
    }
    if (c->est_div != 0u && angle_src_is_estimator(c->angle_src) &&
        ph[FW_TEL_EST] == f->tel.at[FW_TEL_EST]) {
        send_est(f);
    }
    tel_advance(f);
}
