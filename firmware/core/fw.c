#include "fw.h"
#include "transforms.h"

#include <math.h>
#include <string.h>

#define FW_STOP_RAMP_RPM_S 3000.0f   /* quick-stop deceleration */
#define FW_STOP_SPEED_RPM 3.0f       /* below this, with the reference at zero, PWM goes off */
#define FW_STOP_HOLD_S 0.05f         /* zero reference held this long before PWM off */
#define FW_STOP_TIMEOUT_S 3.0f       /* PWM off after this long in any case */
#define FW_RPM_PER_RAD_S 9.549296585513720f
#define FW_SPEED_REF_WEIGHT 0.7f     /* set-point weight of the speed PI's proportional path */
#define FW_DITHER_PERIOD 22u         /* q-current dither: not a divisor of the speed-loop period */
#define FW_DITHER_GAIN 0.6f          /* peak-to-peak, as a fraction of one vector's current step */

/* stop reasons (arg of the stopped event) */
#define FW_STOP_HOST 0
#define FW_STOP_ABORT 1
#define FW_STOP_FAULT 2
#define FW_STOP_HEARTBEAT 3
#define FW_STOP_PROFILE_END 4

/* ------------------------------------------------------------------ link helpers */

bool fw_send(fw_t *f, uint16_t msg_id, const uint16_t *payload, uint16_t n)
{
    if (f->link == FW_LINK_CAN) {   /* docs/can.md: whole messages queued as frames, or dropped */
        bool ok = can_link_send(&f->can, msg_id, f->tx_seq, payload, n);
        f->tx_seq = (uint16_t)((f->tx_seq + 1u) & 0xFFu);
        f->tx.dropped += ok ? 0u : 1u;
        return ok;
    }
    uint16_t len = frame_encode(msg_id, f->tx_seq, payload, n, f->frame_buf,
                                (uint16_t)(sizeof(f->frame_buf) / sizeof(f->frame_buf[0])));
    f->tx_seq = (uint16_t)((f->tx_seq + 1u) & 0xFFu);
    if (len == 0u) {
        f->tx.dropped++;
        return false;
    }
    return txq_push(&f->tx, f->frame_buf, len);
}

static void send_ack(fw_t *f, uint16_t cmd_id, uint16_t cmd_seq, uint16_t status)
{
    proto_ack_t a;
    uint16_t n;
    a.cmd_id = cmd_id;
    a.cmd_seq = cmd_seq;
    a.status = status;
    n = proto_ack_pack(&a, f->payload_buf);
    (void)fw_send(f, PROTO_ID_ACK, f->payload_buf, n);
}

static void send_event(fw_t *f, uint16_t code, int32_t arg)
{
    proto_event_t e;
    uint16_t n;
    e.tick = f->tick;
    e.code = code;
    e.arg = arg;
    n = proto_event_pack(&e, f->payload_buf);
    (void)fw_send(f, PROTO_ID_EVENT, f->payload_buf, n);
}

static void send_identify(fw_t *f)
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
    n = proto_identify_pack(&m, f->payload_buf);
    (void)fw_send(f, PROTO_ID_IDENTIFY, f->payload_buf, n);
}

static void send_capture_chunk(fw_t *f, uint16_t offset)
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
    n = proto_capture_chunk_pack(&c, f->payload_buf);
    (void)fw_send(f, PROTO_ID_CAPTURE_CHUNK, f->payload_buf, n);
}

/* ------------------------------------------------------------------ state changes */

void fw_set_board_hook(fw_t *f, fw_board_msg_fn fn, void *ctx)
{
    f->board_msg = fn;
    f->board_ctx = ctx;
}

bool fw_active(const fw_t *f)
{
    return f->state == PROTO_STATE_RUNNING || f->state == PROTO_STATE_STOPPING;
}

static void enter_stopping(fw_t *f, uint16_t reason)
{
    if (f->state == PROTO_STATE_RUNNING) {
        f->state = PROTO_STATE_STOPPING;
        f->stop_reason = reason;
        f->stop_ref_rpm = f->sig.speed_ref_rpm;
        f->stop_ticks = 0u;
        f->stop_hold_ticks = 0u;
    }
}

static void send_status(fw_t *f);

static void pwm_off(fw_t *f, uint16_t new_state, uint16_t reason)
{
    f->state = new_state;
    f->stop_reason = reason;
    send_event(f, PROTO_EVENT_STOPPED, (int32_t)reason);
    send_status(f);
}

static void trip(fw_t *f, uint16_t fault_bits)
{
    f->faults = (uint16_t)(f->faults | fault_bits);
    send_event(f, PROTO_EVENT_FAULT, (int32_t)fault_bits);
    if (capture_freeze(&f->cap)) {   /* the whole buffer leads up to the fault */
        send_event(f, PROTO_EVENT_CAPTURE_TRIGGERED, -1);
    }
    pwm_off(f, PROTO_STATE_FAULT, FW_STOP_FAULT);
}

/* ------------------------------------------------------------------ identification */

static void ident_init(fw_t *f)
{
    est_cfg_t ec;
    idw_cfg_t wc;
    rinj_cfg_t rc;
    uint16_t i;
    est_cfg_default(&ec, f->motor.r_s_ohm, f->motor.l_d_h, f->motor.l_q_h, f->motor.psi_f_wb,
                    f->motor.pole_pairs);
    est_rls_init(&f->est_rls, &ec);
    est_adaline_init(&f->est_ada, &ec);
    est_nlms_init(&f->est_nlms, &ec);
    memset(f->est_out, 0, sizeof(f->est_out));
    wc.n_periods = f->ctrl.id_window;
    wc.ts_s = f->ctrl.ts_s;
    idw_init(&f->idw, &wc);
    rc.sep_min = 0.02f;
    rc.n_window = f->ctrl.id_window >= 2u ? f->ctrl.id_window : 20u;
    rc.ts_s = f->ctrl.ts_s;
    rc.l_d_h = f->motor.l_d_h;
    rc.l_q_h = f->motor.l_q_h;
    rinj_init(&f->rinj, &rc);
    memset(&f->rinj_out, 0, sizeof(f->rinj_out));
    f->have_injection = false;
    for (i = 0u; i < f->prof.n_declared && i < PROFILE_MAX_SEGMENTS; i++) {
        if (f->prof.seg[i].kind == PROFILE_KIND_IDENTIFY_R) {
            f->have_injection = true;
        }
    }
    f->r_identified = false;
    f->r_injecting = false;
    f->r_ident_ohm = 0.0f;
    f->pred_latched = false;
    f->i_d_base_a = 0.0f;
    f->id_ref_prev_a = 0.0f;
    f->idw_step_seen = true;
    f->id_step_hold = 0u;
    f->seg_kind = PROFILE_KIND_RUN;
    f->seg_inject_a = 0.0f;
    f->seg_inject_hz = 0.0f;
    f->seg_tick = 0u;
    f->seg_ticks = 0u;
}

/* The R an estimator reports: the injection's while it runs, 0 before it (R unknown), then the
 * estimator's own (initialised from the injection, refined online). */
static float est_r_report(const fw_t *f, uint16_t k)
{
    if (f->r_injecting && !f->r_identified) {
        return f->rinj_out.r_s_ohm;
    }
    if (f->have_injection && !f->r_identified) {
        return 0.0f;
    }
    return f->est_out[k].r_s_ohm;
}

/* Parameters of the MPCC predictor: the chosen estimator once it has converged (R from the
 * injection until then), else the motor file's values times the profile's mismatch factors. */
static void predictor_params(fw_t *f, mpcc_in_t *mi)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    mi->r_s_ohm = f->motor.r_s_ohm * c->pred_scale_r_s;
    mi->l_d_h = f->motor.l_d_h * c->pred_scale_l_d;
    mi->l_q_h = f->motor.l_q_h * c->pred_scale_l_q;
    mi->psi_f_wb = f->motor.psi_f_wb * c->pred_scale_psi_f;
    if (c->identify != 0u && c->predictor != PROTO_ESTIMATOR_NOMINAL &&
        c->predictor <= PROTO_ESTIMATOR_NLMS_ADALINE) {
        const est_out_t *o = &f->est_out[c->predictor - 1u];
        if (f->r_identified) {
            mi->r_s_ohm = f->r_ident_ohm;
        }
        if (!f->pred_latched && o->converged) {
            f->pred_latched = true;
        }
        if (f->pred_latched && o->l_d_h > 0.0f && o->l_q_h > 0.0f) {
            mi->r_s_ohm = o->r_s_ohm;
            mi->l_d_h = o->l_d_h;
            mi->l_q_h = o->l_q_h;
            mi->psi_f_wb = o->psi_f_wb;
        }
    }
    f->pred_r_s_ohm = mi->r_s_ohm;
    f->pred_l_d_h = mi->l_d_h;
    f->pred_l_q_h = mi->l_q_h;
    f->pred_psi_f_wb = mi->psi_f_wb;
}

/* d-current reference of this period: identify_r's injection level (two levels: inject_a over
 * the first half, inject_a / 2 over the second), or the speed loop's plus the square-wave
 * excitation of the segment. */
static float d_current_ref(const fw_t *f)
{
    if (f->seg_kind == PROFILE_KIND_IDENTIFY_R) {
        return 2u * f->seg_tick < f->seg_ticks ? f->seg_inject_a : 0.5f * f->seg_inject_a;
    }
    if (f->seg_inject_a != 0.0f && f->seg_inject_hz > 0.0f) {
        const float ph = (float)f->seg_tick * f->ctrl.ts_s * f->seg_inject_hz;
        const float frac = ph - floorf(ph);
        return f->i_d_base_a + (frac < 0.5f ? f->seg_inject_a : -f->seg_inject_a);
    }
    return f->i_d_base_a;
}

/* After the MPCC step: feed the R injection or the window averager and the three estimators. */
static void ident_step(fw_t *f, const fw_meas_t *m, const mpcc_out_t *mo)
{
    if (f->seg_kind == PROFILE_KIND_IDENTIFY_R) {
        const uint32_t half = f->seg_ticks / 2u;
        const uint32_t t_in = f->seg_tick < half ? f->seg_tick : f->seg_tick - half;
        const uint32_t len = f->seg_tick < half ? half : f->seg_ticks - half;
        f->r_injecting = true;
        if ((float)t_in >= FW_R_SETTLE_FRAC * (float)len) {
            rinj_in_t ri;
            ri.i_d_a = f->sig.i_d_a;
            ri.i_q_a = f->sig.i_q_a;
            ri.u_d_v = mo->u_d_avg_v;
            ri.u_q_v = mo->u_q_avg_v;
            ri.theta_e_rad = f->sig.theta_e_est_rad;
            ri.i_a_a = m->i_a_a;
            ri.i_b_a = m->i_b_a;
            ri.i_c_a = m->i_c_a;
            rinj_step(&f->rinj, &ri, &f->rinj_out);
        } else {
            rinj_gap(&f->rinj);   /* settling: the windows must not span the level change */
        }
        if (f->seg_tick + 1u >= f->seg_ticks && f->rinj_out.r_s_ohm > 0.0f) {
            f->r_ident_ohm = f->rinj_out.r_s_ohm;
            f->r_identified = true;
            f->r_injecting = false;
            est_rls_set_r(&f->est_rls, f->r_ident_ohm);
            est_adaline_set_r(&f->est_ada, f->r_ident_ohm);
            est_nlms_set_r(&f->est_nlms, f->r_ident_ohm);
            f->est_out[FW_EST_RLS].r_s_ohm = f->r_ident_ohm;
            f->est_out[FW_EST_ADALINE].r_s_ohm = f->r_ident_ohm;
            f->est_out[FW_EST_NLMS].r_s_ohm = f->r_ident_ohm;
            send_event(f, PROTO_EVENT_R_IDENTIFIED, (int32_t)(f->r_ident_ohm * 1000.0f + 0.5f));
        }
        idw_reset(&f->idw);
        return;
    }
    f->r_injecting = false;
    if (f->ctrl.identify != 0u) {
        idw_in_t wi;
        id_sample_t smp;
        /* The encoder count is the floor of the angle: on average the true angle is half a count
         * ahead. The steady-state equations are sensitive to that bias (a rotation by delta moves
         * delta * u_q ~ 0.1 V into u_d at 1000 r/min, +0.4 % on L_q), so the estimators see u and i
         * in the frame of the mid-count angle: x(theta + delta) = rot(-delta) x(theta). */
        const float dl = f->ctrl.enc_counts > 0u ?
                         FW_PI_F * (float)f->motor.pole_pairs / (float)f->ctrl.enc_counts : 0.0f;
        wi.i_d_a = f->sig.i_d_a + dl * f->sig.i_q_a;
        wi.i_q_a = f->sig.i_q_a - dl * f->sig.i_d_a;
        wi.u_d_v = mo->u_d_avg_v + dl * mo->u_q_avg_v;
        wi.u_q_v = mo->u_q_avg_v - dl * mo->u_d_avg_v;
        wi.omega_e_rad_s = f->enc_out.omega_e_rad_s;
        if (idw_step(&f->idw, &wi, &smp)) {
            /* (6) is a steady-state equation: a window with a step of the i_d reference (the
             * excitation's edges) carries the current controller's transient and is skipped */
            if (!f->idw_step_seen && (f->seg_flags & PROFILE_FLAG_HOLD_EST) == 0u) {
                est_rls_step(&f->est_rls, &smp, &f->est_out[FW_EST_RLS]);
                est_adaline_step(&f->est_ada, &smp, &f->est_out[FW_EST_ADALINE]);
                est_nlms_step(&f->est_nlms, &smp, &f->est_out[FW_EST_NLMS]);
            }
            f->idw_step_seen = false;
        }
        if (fabsf(f->sig.i_d_ref_a - f->id_ref_prev_a) > FW_ID_STEP_A) {
            f->id_step_hold = FW_ID_STEP_HOLD;
        }
        if (f->id_step_hold > 0u) {
            f->idw_step_seen = true;   /* this period belongs to the running window */
            f->id_step_hold--;
        }
        f->id_ref_prev_a = f->sig.i_d_ref_a;
    }
}

static uint16_t start_run(fw_t *f)
{
    mpcc_cfg_t mc;
    speed_pi_cfg_t sc;
    enc_cfg_t ec;
    dither_cfg_t dc;
    if (!f->have_motor || !f->have_ctrl || !profile_complete(&f->prof)) {
        return PROTO_ACK_STATUS_BAD_STATE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    mpcc_cfg_default(&mc);
    mc.ts_s = f->ctrl.ts_s;
    mc.rho = f->ctrl.rho;
    mc.dead_time_s = f->ctrl.dead_time_s;
    mc.v_drop_v = f->ctrl.v_drop_v;
    mc.i_dt_a = f->ctrl.i_dt_a;
    mpcc_init(&f->mpcc, &mc);

    sc.kp_a_per_rad_s = f->ctrl.speed_kp_a_per_rad_s;
    sc.ki_a_per_rad = f->ctrl.speed_ki_a_per_rad;
    sc.ts_s = f->ctrl.ts_s * (float)f->ctrl.speed_div;
    sc.out_max_a = f->motor.i_max_a;
    speed_pi_init(&f->spi, &sc);
    speed_pi_set_ref_weight(&f->spi, FW_SPEED_REF_WEIGHT);

    ec.counts = f->ctrl.enc_counts;
    ec.pole_pairs = f->motor.pole_pairs;
    ec.offset_rad = f->ctrl.enc_offset_rad;
    ec.bw_rad_s = f->ctrl.speed_obs_bw_rad_s;
    ec.ts_s = f->ctrl.ts_s;
    enc_init(&f->enc, &ec);

    dc.period = FW_DITHER_PERIOD;
    dc.gain = FW_DITHER_GAIN;
    dither_init(&f->dither, &dc);

    ident_init(f);
    capture_init(&f->cap, f->ctrl.capture_pre);
    profile_start(&f->prof, f->ctrl.ts_s);
    memset(&f->sig, 0, sizeof(f->sig));
    f->i_s_ref_a = 0.0f;
    f->speed_div_count = 0u;
    f->faults = 0u;
    f->tick = 0u;
    f->hb_isr = f->isr_count;
    f->hb_lost = false;
    f->state = PROTO_STATE_RUNNING;
    f->stop_reason = 0u;
    f->stop_ref_rpm = 0.0f;
    return PROTO_ACK_STATUS_OK;
}

/* ------------------------------------------------------------------ commands */

static uint16_t cmd_config_motor(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_config_motor_t m;
    if (!proto_config_motor_unpack(&m, p, n)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    if (m.pole_pairs == 0u || !(m.r_s_ohm > 0.0f) || !(m.l_d_h > 0.0f) || !(m.l_q_h > 0.0f) ||
        !(m.psi_f_wb >= 0.0f) || !(m.j_kgm2 > 0.0f) || !(m.i_max_a > 0.0f) ||
        !(m.i_trip_a > m.i_max_a) || !(m.speed_max_rpm > 0.0f) ||
        !(m.speed_trip_rpm > m.speed_max_rpm) || !(m.v_dc_max_v > m.v_dc_min_v)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    f->motor.pole_pairs = m.pole_pairs;
    f->motor.r_s_ohm = m.r_s_ohm;
    f->motor.l_d_h = m.l_d_h;
    f->motor.l_q_h = m.l_q_h;
    f->motor.psi_f_wb = m.psi_f_wb;
    f->motor.j_kgm2 = m.j_kgm2;
    f->motor.i_max_a = m.i_max_a;
    f->motor.speed_max_rpm = m.speed_max_rpm;
    f->limits.i_trip_a = m.i_trip_a;
    f->limits.speed_trip_rpm = m.speed_trip_rpm;
    f->limits.v_dc_min_v = m.v_dc_min_v;
    f->limits.v_dc_max_v = m.v_dc_max_v;
    f->have_motor = true;
    return PROTO_ACK_STATUS_OK;
}

static uint16_t cmd_config_ctrl(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_config_ctrl_t c;
    if (!proto_config_ctrl_unpack(&c, p, n)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    if (!(c.ts_s >= 1e-5f && c.ts_s <= 1e-3f) || c.speed_div == 0u || !(c.rho > 0.0f) ||
        !(c.heartbeat_timeout_s > 0.0f) || c.enc_counts < 4u || !(c.speed_obs_bw_rad_s > 0.0f) ||
        c.current_ref > PROTO_CURRENT_REF_MTPA || c.current_ctrl != PROTO_CURRENT_CTRL_MPCC ||
        c.capture_pre >= CAPTURE_LEN || c.speed_kp_a_per_rad_s < 0.0f || c.speed_ki_a_per_rad < 0.0f ||
        c.identify > 1u || c.predictor > PROTO_ESTIMATOR_NLMS_ADALINE ||
        (c.identify != 0u && c.id_window < 2u) || !(c.pred_scale_l_d > 0.0f) ||
        !(c.pred_scale_l_q > 0.0f) || !(c.pred_scale_psi_f >= 0.0f) || !(c.pred_scale_r_s >= 0.0f) ||
        !(c.pred_scale_l_d <= 100.0f && c.pred_scale_l_q <= 100.0f && c.pred_scale_psi_f <= 100.0f &&
          c.pred_scale_r_s <= 100.0f)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    f->ctrl = c;
    f->have_ctrl = true;
    return PROTO_ACK_STATUS_OK;
}

static uint16_t cmd_profile_segment(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_profile_segment_t s;
    profile_segment_t seg;
    if (!proto_profile_segment_unpack(&s, p, n)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    if (f->have_motor && (fabsf(s.speed_rpm) > f->motor.speed_max_rpm)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    seg.duration_s = s.duration_s;
    seg.speed_rpm = s.speed_rpm;
    seg.ramp_rpm_s = s.ramp_rpm_s;
    seg.load_nm = s.load_nm;
    seg.flags = s.flags;
    seg.kind = s.kind;
    seg.inject_a = s.inject_a;
    seg.inject_hz = s.inject_hz;
    if (s.kind > PROFILE_KIND_IDENTIFY_R || !(s.inject_hz >= 0.0f) || !(fabsf(s.inject_a) <= 1e3f) ||
        (s.kind == PROFILE_KIND_IDENTIFY_R && (s.speed_rpm != 0.0f || !(s.inject_a != 0.0f)))) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (f->have_motor && fabsf(s.inject_a) > f->motor.i_max_a) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    return profile_set(&f->prof, s.index, &seg) ? PROTO_ACK_STATUS_OK : PROTO_ACK_STATUS_BAD_VALUE;
}

static void handle_frame(fw_t *f, uint16_t id, uint16_t seq, const uint16_t *p, uint16_t n)
{
    uint16_t st = PROTO_ACK_STATUS_OK;
    f->rx_frames++;
    switch (id) {
    case PROTO_ID_HELLO:
        send_identify(f);
        return;
    case PROTO_ID_HEARTBEAT:
        f->hb_isr = f->isr_count;
        return;
    case PROTO_ID_CAPTURE_READ: {
        proto_capture_read_t r;
        if (proto_capture_read_unpack(&r, p, n)) {
            send_capture_chunk(f, r.offset);
            return;
        }
        st = PROTO_ACK_STATUS_BAD_VALUE;
        break;
    }
    case PROTO_ID_CONFIG_MOTOR:
        st = cmd_config_motor(f, p, n);
        break;
    case PROTO_ID_CONFIG_CTRL:
        st = cmd_config_ctrl(f, p, n);
        break;
    case PROTO_ID_PROFILE_CLEAR: {
        proto_profile_clear_t c;
        if (!proto_profile_clear_unpack(&c, p, n) || c.n_segments > PROFILE_MAX_SEGMENTS) {
            st = PROTO_ACK_STATUS_BAD_VALUE;
        } else if (fw_active(f)) {
            st = PROTO_ACK_STATUS_BUSY;
        } else {
            profile_clear(&f->prof, c.n_segments);
        }
        break;
    }
    case PROTO_ID_PROFILE_SEGMENT:
        st = cmd_profile_segment(f, p, n);
        break;
    case PROTO_ID_START:
        st = start_run(f);
        if (st == PROTO_ACK_STATUS_OK) {
            send_ack(f, id, seq, st);
            send_event(f, PROTO_EVENT_STARTED, 0);
            return;
        }
        break;
    case PROTO_ID_STOP:
        if (f->state == PROTO_STATE_RUNNING) {
            enter_stopping(f, FW_STOP_HOST);
        } else if (!fw_active(f)) {
            st = PROTO_ACK_STATUS_OK;   /* already stopped: idempotent */
        }
        break;
    case PROTO_ID_ABORT:
        if (fw_active(f)) {
            pwm_off(f, PROTO_STATE_IDLE, FW_STOP_ABORT);
        }
        break;
    default:
        st = f->board_msg != 0 ? f->board_msg(f->board_ctx, id, p, n) : PROTO_ACK_STATUS_UNKNOWN;
        break;
    }
    send_ack(f, id, seq, st);
}

void fw_can_rx(fw_t *f, uint16_t id, const uint16_t *data, uint16_t dlc)
{
    int16_t r = can_link_rx(&f->can, id, data, dlc);
    if (r == CAN_RX_MSG) {
        f->link = f->can.msg_id == PROTO_ID_HELLO ? FW_LINK_CAN : f->link;
        handle_frame(f, f->can.msg_id, f->can.seq, f->can.payload, f->can.payload_len);
    } else if (r < 0) {
        f->rx_bad++;
    }
}

void fw_rx_octet(fw_t *f, uint16_t octet)
{
    int16_t r = frame_parser_push(&f->rx, octet);
    if (r == FRAME_OK) {
        f->link = f->rx.msg_id == PROTO_ID_HELLO ? FW_LINK_SERIAL : f->link;
        handle_frame(f, f->rx.msg_id, f->rx.seq, f->rx.payload, f->rx.payload_len);
    } else if (r < 0) {
        f->rx_bad++;
    }
}

bool fw_tx_pop(fw_t *f, uint16_t *octet)
{
    return txq_pop(&f->tx, octet);
}

uint16_t fw_tx_pop_n(fw_t *f, uint16_t *out, uint16_t max)
{
    return txq_pop_n(&f->tx, out, max);
}

/* ------------------------------------------------------------------ telemetry */

static void send_status(fw_t *f)
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
        s.tx_dropped = f->tx.dropped;
        s.rx_bad = (uint16_t)(f->rx_bad > 0xFFFFu ? 0xFFFFu : f->rx_bad);
        s.rx_frames = f->rx_frames;
        s.hb_age_ms = (uint16_t)(age_ms > 65535.0f ? 65535.0f : age_ms);
        s.capture_count = capture_count(&f->cap);
        n = proto_status_pack(&s, f->payload_buf);
        (void)fw_send(f, PROTO_ID_STATUS, f->payload_buf, n);
    }
}

/* Parameter frame of slot 0 (the motor file's values as the predictor sees them) or of estimator
 * slot k (1..FW_N_EST). */
static void send_params(fw_t *f, uint16_t slot)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    proto_params_t pm;
    uint16_t n;
    bool nominal_feeds = c->identify == 0u || c->predictor == PROTO_ESTIMATOR_NOMINAL ||
                         !f->pred_latched;
    pm.tick = f->tick;
    if (slot == 0u) {
        pm.estimator = PROTO_ESTIMATOR_NOMINAL;
        pm.flags = nominal_feeds ? 4u : 0u;
        pm.l_d_h = f->motor.l_d_h * c->pred_scale_l_d;
        pm.l_q_h = f->motor.l_q_h * c->pred_scale_l_q;
        pm.psi_f_wb = f->motor.psi_f_wb * c->pred_scale_psi_f;
        pm.r_s_ohm = f->motor.r_s_ohm * c->pred_scale_r_s;
    } else {
        const est_out_t *o = &f->est_out[slot - 1u];
        pm.estimator = slot;
        pm.flags = (uint16_t)((o->excited ? 1u : 0u) | (o->converged ? 2u : 0u) |
                              ((!nominal_feeds && c->predictor == slot) ? 4u : 0u));
        pm.l_d_h = o->l_d_h;
        pm.l_q_h = o->l_q_h;
        pm.psi_f_wb = o->psi_f_wb;
        pm.r_s_ohm = est_r_report(f, (uint16_t)(slot - 1u));
    }
    n = proto_params_pack(&pm, f->payload_buf);
    (void)fw_send(f, PROTO_ID_PARAMS, f->payload_buf, n);
}

/* Telemetry streams on staggered phases, so that a control period builds at most one frame with
 * the default rates (fast at phase 0, parameter slots at 1..4, status at 5): the ISR's worst
 * case stays within budget on the F28335 (docs/board-f28335.md). */
#define FW_PHASE_PARAMS 1u
#define FW_PHASE_STATUS (FW_PHASE_PARAMS + FW_N_EST + 1u)

static void send_telemetry(fw_t *f)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    uint16_t n;
    if (c->fast_div != 0u && (f->tick % c->fast_div) == 0u) {
        proto_telem_fast_t t;
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
        t.u_d_v = f->sig.u_d_v;
        t.u_q_v = f->sig.u_q_v;
        t.load_nm = f->sig.load_nm;
        n = proto_telem_fast_pack(&t, f->payload_buf);
        (void)fw_send(f, PROTO_ID_TELEM_FAST, f->payload_buf, n);
    }
    if (c->params_div != 0u) {
        uint32_t ph = f->tick % c->params_div;
        uint16_t slots = (uint16_t)(c->identify != 0u ? FW_N_EST + 1u : 1u);
        if (ph >= FW_PHASE_PARAMS && ph < FW_PHASE_PARAMS + slots) {
            send_params(f, (uint16_t)(ph - FW_PHASE_PARAMS));
        }
    }
    if (c->status_div != 0u && (f->tick % c->status_div) == FW_PHASE_STATUS % c->status_div) {
        send_status(f);
    }
}

/* ------------------------------------------------------------------ control period */

static void check_faults(fw_t *f, const fw_meas_t *m)
{
    uint16_t bits = 0u;
    float it = f->limits.i_trip_a;
    if (fabsf(m->i_a_a) > it || fabsf(m->i_b_a) > it || fabsf(m->i_c_a) > it) {
        bits |= PROTO_FAULT_OVER_CURRENT;
    }
    if (fabsf(f->enc_out.speed_rpm) > f->limits.speed_trip_rpm) {
        bits |= PROTO_FAULT_OVER_SPEED;
    }
    if (m->v_dc_v < f->limits.v_dc_min_v) {
        bits |= PROTO_FAULT_DC_UNDER_VOLTAGE;
    }
    if (m->v_dc_v > f->limits.v_dc_max_v) {
        bits |= PROTO_FAULT_DC_OVER_VOLTAGE;
    }
    if (bits != 0u) {
        trip(f, bits);
    }
}

static void check_heartbeat(fw_t *f)
{
    float age_s = (float)(f->isr_count - f->hb_isr) * f->ctrl.ts_s;
    if (!f->hb_lost && age_s > f->ctrl.heartbeat_timeout_s) {
        f->hb_lost = true;
        f->faults = (uint16_t)(f->faults | PROTO_FAULT_HEARTBEAT);
        send_event(f, PROTO_EVENT_HEARTBEAT_LOST, (int32_t)(age_s * 1000.0f));
        enter_stopping(f, FW_STOP_HEARTBEAT);
    }
}

/* Speed reference and load for this period, from the profile or the stop ramp. */
static void reference(fw_t *f, float *speed_ref_rpm, float *load_nm)
{
    if (f->state == PROTO_STATE_RUNNING) {
        profile_out_t po;
        profile_step(&f->prof, f->ctrl.ts_s, &po);
        if (po.segment_started) {
            send_event(f, PROTO_EVENT_SEGMENT_START, (int32_t)po.index);
            if ((po.flags & PROFILE_FLAG_CAPTURE) != 0u && capture_trigger(&f->cap)) {
                send_event(f, PROTO_EVENT_CAPTURE_TRIGGERED, (int32_t)po.index);
            }
        }
        if (po.finished) {
            send_event(f, PROTO_EVENT_PROFILE_DONE, (int32_t)po.index);
            enter_stopping(f, FW_STOP_PROFILE_END);
        } else {
            *speed_ref_rpm = po.speed_ref_rpm;
            *load_nm = po.load_nm;
            f->seg_kind = po.kind;
            f->seg_flags = po.flags;
            f->seg_inject_a = po.inject_a;
            f->seg_inject_hz = po.inject_hz;
            f->seg_tick = po.tick_in_seg;
            f->seg_ticks = po.seg_ticks;
            return;
        }
    }
    f->seg_kind = PROFILE_KIND_RUN;
    f->seg_flags = PROFILE_FLAG_HOLD_EST;   /* no identification while stopping */
    f->seg_inject_a = 0.0f;
    /* stopping: quick-stop ramp to zero, load released */
    f->stop_ref_rpm = profile_ramp(f->stop_ref_rpm, 0.0f, FW_STOP_RAMP_RPM_S, f->ctrl.ts_s);
    *speed_ref_rpm = f->stop_ref_rpm;
    *load_nm = 0.0f;
}

void fw_isr(fw_t *f, const fw_meas_t *m, fw_cmd_t *cmd)
{
    float speed_ref_rpm = 0.0f, load_nm = 0.0f, c, s, i_al, i_be;
    fw_dq_t idq_ref;
    mpcc_in_t mi;
    mpcc_out_t mo;
    capture_sample_t cs;

    f->isr_count++;
    f->sig.v_dc_v = m->v_dc_v;
    cmd->pwm_on = false;
    cmd->s_a = 0u;
    cmd->s_b = 0u;
    cmd->s_c = 0u;
    cmd->load_nm = 0.0f;
    if (!fw_active(f)) {
        return;
    }

    /* angle and speed slot: the encoder (its observer starts where the rotor is) */
    if (f->tick == 0u) {
        enc_reset(&f->enc, m->enc_count);
    }
    enc_step(&f->enc, m->enc_count, &f->enc_out);
    f->sig.theta_e_rad = f->enc_out.theta_e_rad;
    f->sig.speed_rpm = f->enc_out.speed_rpm;
    f->sig.theta_e_est_rad = f->enc_out.theta_e_rad;
    f->sig.speed_est_rpm = f->enc_out.speed_rpm;
    f->sig.omega_e_rad_s = f->enc_out.omega_e_rad_s;

    c = cosf(f->sig.theta_e_est_rad);
    s = sinf(f->sig.theta_e_est_rad);
    i_al = m->i_a_a;
    i_be = (m->i_a_a + 2.0f * m->i_b_a) * 0.57735026918963f;
    f->sig.i_d_a = c * i_al + s * i_be;
    f->sig.i_q_a = -s * i_al + c * i_be;

    /* capture: the sample with the switch state applied while it was taken */
    cs.i_a_a = m->i_a_a;
    cs.i_b_a = m->i_b_a;
    cs.i_c_a = m->i_c_a;
    cs.s_abc = f->mpcc.sw_prev;
    cs.v_dc_v = m->v_dc_v;
    cs.theta_e_rad = f->sig.theta_e_rad;
    cs.omega_e_rad_s = f->enc_out.omega_e_rad_s;
    capture_record(&f->cap, f->tick, &cs);

    check_faults(f, m);
    if (!fw_active(f)) {
        send_telemetry(f);
        f->tick++;
        return;
    }
    check_heartbeat(f);

    reference(f, &speed_ref_rpm, &load_nm);
    if (!fw_active(f)) {   /* reference() may end the run */
        send_telemetry(f);
        f->tick++;
        return;
    }
    f->sig.speed_ref_rpm = speed_ref_rpm;
    f->sig.load_nm = load_nm;

    /* speed loop (identify_r: off, the d axis carries the injection and the q axis nothing) */
    f->speed_div_count++;
    if (f->seg_kind == PROFILE_KIND_IDENTIFY_R) {
        speed_pi_reset(&f->spi, 0.0f);
        f->i_s_ref_a = 0.0f;
        f->i_d_base_a = 0.0f;
        f->sig.i_q_ref_a = 0.0f;
    } else if (f->speed_div_count >= f->ctrl.speed_div) {
        f->speed_div_count = 0u;
        f->i_s_ref_a = speed_pi_step(&f->spi, speed_ref_rpm / FW_RPM_PER_RAD_S,
                                     f->enc_out.omega_m_rad_s);
        mtpa_split(&f->motor, f->ctrl.current_ref, f->i_s_ref_a, &idq_ref);
        f->i_d_base_a = idq_ref.d;
        f->sig.i_q_ref_a = idq_ref.q;
    }
    f->sig.i_d_ref_a = d_current_ref(f);

    /* current control slot: MPCC */
    mi.i_d_a = f->sig.i_d_a;
    mi.i_q_a = f->sig.i_q_a;
    mi.i_d_ref_a = f->sig.i_d_ref_a;
    mi.i_q_ref_a = f->sig.i_q_ref_a +
                   dither_step(&f->dither, 0.6666667f * m->v_dc_v * f->ctrl.ts_s / f->motor.l_q_h);
    mi.theta_e_rad = f->sig.theta_e_est_rad;
    mi.omega_e_rad_s = f->enc_out.omega_e_rad_s;
    mi.v_dc_v = m->v_dc_v;
    predictor_params(f, &mi);
    mpcc_step_cs(&f->mpcc, &mi, c, s, &mo);   /* c, s: cos, sin of mi.theta_e_rad (above) */
    ident_step(f, m, &mo);
    f->sig.u_d_v = mo.u_d_v;
    f->sig.u_q_v = mo.u_q_v;
    cmd->s_a = mo.s_a;
    cmd->s_b = mo.s_b;
    cmd->s_c = mo.s_c;
    cmd->pwm_on = true;
    cmd->load_nm = load_nm;

    send_telemetry(f);
    f->tick++;

    /* end of a stop: reference at zero and the rotor (nearly) still for a while, or too long */
    if (f->state == PROTO_STATE_STOPPING) {
        f->stop_ticks++;
        if (f->stop_ref_rpm == 0.0f && fabsf(f->enc_out.speed_rpm) < FW_STOP_SPEED_RPM) {
            f->stop_hold_ticks++;
        } else {
            f->stop_hold_ticks = 0u;
        }
    }
    if (f->state == PROTO_STATE_STOPPING &&
        ((float)f->stop_hold_ticks * f->ctrl.ts_s >= FW_STOP_HOLD_S ||
         (float)f->stop_ticks * f->ctrl.ts_s >= FW_STOP_TIMEOUT_S)) {
        cmd->pwm_on = false;
        pwm_off(f, f->stop_reason == FW_STOP_PROFILE_END ? PROTO_STATE_DONE : PROTO_STATE_IDLE,
                f->stop_reason);
    }
}

void fw_init(fw_t *f, const fw_cfg_t *cfg)
{
    memset(f, 0, sizeof(*f));
    f->cfg = *cfg;
    frame_parser_init(&f->rx);
    can_link_init(&f->can, cfg->can_node);
    txq_init(&f->tx);
    capture_init(&f->cap, 0u);
    f->state = PROTO_STATE_IDLE;
}
