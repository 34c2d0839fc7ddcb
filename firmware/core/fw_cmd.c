/* Commands from the host: parsing (serial frames and CAN), validation, acknowledgement. */
#include "fw_internal.h"
#include "transforms.h"

#include <math.h>
#include <string.h>

/* ------------------------------------------------------------------ commands */

/* Finite (not NaN, not infinite) without relying on the library's classification macros:
 * x - x is 0 for every finite x and NaN otherwise. */
static bool finite_f(float x)
{
    return (x - x) == 0.0f;
}

static bool within(float x, float lo, float hi)
{
    return x >= lo && x <= hi; /* false for NaN */
}

static uint16_t cmd_config_motor(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_config_motor_t m;
    if (!proto_config_motor_unpack(&m, p, n)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    if (m.pole_pairs == 0u || !within(m.r_s_ohm, 1e-6f, 1e3f) || !within(m.l_d_h, 1e-9f, 10.0f) ||
        !within(m.l_q_h, 1e-9f, 10.0f) || !within(m.psi_f_wb, 0.0f, 100.0f) ||
        !within(m.j_kgm2, 1e-9f, 1e3f) || !(m.i_max_a > 0.0f) || !(m.i_trip_a > m.i_max_a) ||
        !within(m.i_trip_a, 0.0f, FW_I_TRIP_MAX_A) || !(m.speed_max_rpm > 0.0f) ||
        !(m.speed_trip_rpm > m.speed_max_rpm) ||
        !within(m.speed_trip_rpm, 0.0f, FW_SPEED_TRIP_MAX_RPM) ||
        !within(m.v_dc_min_v, 0.0f, FW_V_DC_MAX_V) || !(m.v_dc_max_v > m.v_dc_min_v) ||
        !within(m.v_dc_max_v, 0.0f, FW_V_DC_MAX_V)) {
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

/* The sensorless estimator's configuration (docs/sensorless.md); the Gamma table's nodes follow
 * in gamma_node frames. */
static uint16_t cmd_config_sensorless(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_config_sensorless_t c;
    if (!proto_config_sensorless_unpack(&c, p, n)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    if (!within(c.pol_i_pulse_a, 0.0f, FW_I_TRIP_MAX_A) ||
        !within(c.pol_asym_expected, -1.0f, 1.0f) || !within(c.pol_asym_min, 0.0f, 1.0f) ||
        !within(c.hyb_pll_on_rpm, 0.0f, FW_SPEED_TRIP_MAX_RPM) ||
        !within(c.hyb_mras_on_rpm, c.hyb_pll_on_rpm, FW_SPEED_TRIP_MAX_RPM) ||
        !within(c.hyb_blend_s, 0.0f, 1.0f) || !within(c.lock_disagree_rad, 0.0f, 3.2f) ||
        !within(c.lock_disagree_s, 0.0f, FW_HEARTBEAT_MAX_S) ||
        !within(c.lock_conf_min, -1.0f, 1.0f) || !within(c.lock_lost_s, 0.0f, FW_HEARTBEAT_MAX_S) ||
        (uint32_t)c.gam_nd * (uint32_t)c.gam_nq > RERR_TAB_MAX ||
        !within(c.gam_id0_a, -FW_I_TRIP_MAX_A, FW_I_TRIP_MAX_A) ||
        !within(c.gam_iq0_a, -FW_I_TRIP_MAX_A, FW_I_TRIP_MAX_A) ||
        !within(c.gam_did_a, 1e-3f, FW_I_TRIP_MAX_A) ||
        !within(c.gam_diq_a, 1e-3f, FW_I_TRIP_MAX_A) || !within(c.if_i_a, 0.0f, FW_I_TRIP_MAX_A) ||
        !within(c.if_accel_rpm_s, 0.0f, 1e6f) ||
        !within(c.if_handover_rpm, 0.0f, FW_SPEED_TRIP_MAX_RPM) ||
        !within(c.pll_excite_a, 0.0f, FW_I_TRIP_MAX_A)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (f->have_motor &&
        (c.if_i_a > f->motor.i_max_a || c.if_handover_rpm > f->motor.speed_max_rpm ||
         c.pll_excite_a > 0.5f * f->motor.i_max_a)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    f->snl_msg = c;
    f->have_snl = true;
    f->gamma_nodes = 0u;
    f->gamma_tab.nd = c.gam_nd;
    f->gamma_tab.nq = c.gam_nq;
    f->gamma_tab.id0_a = c.gam_id0_a;
    f->gamma_tab.iq0_a = c.gam_iq0_a;
    f->gamma_tab.inv_did = 1.0f / c.gam_did_a;
    f->gamma_tab.inv_diq = 1.0f / c.gam_diq_a;
    return PROTO_ACK_STATUS_OK;
}

/* One node of the Gamma table, in order (the table is used once all have arrived). */
static uint16_t cmd_gamma_node(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_gamma_node_t g;
    if (!proto_gamma_node_unpack(&g, p, n) || !f->have_snl ||
        (uint32_t)g.index >= (uint32_t)f->snl_msg.gam_nd * (uint32_t)f->snl_msg.gam_nq ||
        g.index != f->gamma_nodes || !within(g.g_dd, 1.0f, 1.0e7f) ||
        !within(g.g_qq, 1.0f, 1.0e7f) || !within(g.g_dq, -1.0e7f, 1.0e7f) ||
        !within(g.g_qd, -1.0e7f, 1.0e7f)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    f->gamma_tab.g[g.index][0] = g.g_dd;
    f->gamma_tab.g[g.index][1] = g.g_qq;
    f->gamma_tab.g[g.index][2] = g.g_dq;
    f->gamma_tab.g[g.index][3] = g.g_qd;
    f->gamma_nodes++;
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
    if (!(c.ts_s >= 1e-5f && c.ts_s <= 1e-3f) || c.speed_div == 0u || !within(c.rho, 1e-6f, 1e6f) ||
        !within(c.heartbeat_timeout_s, 1e-3f, FW_HEARTBEAT_MAX_S) || c.enc_counts < 4u ||
        !within(c.speed_obs_bw_rad_s, 1e-3f, FW_GAIN_MAX) || !finite_f(c.enc_offset_e_rad) ||
        !within(c.enc_offset_e_rad, -7.0f, 7.0f) || !within(c.dead_time_s, 0.0f, 1e-4f) ||
        !within(c.v_drop_v, 0.0f, 100.0f) || !within(c.i_dt_a, 0.0f, 100.0f) ||
        !within(c.speed_kp_a_per_rad_s, 0.0f, FW_GAIN_MAX) ||
        !within(c.speed_ki_a_per_rad, 0.0f, FW_GAIN_MAX) ||
        c.current_ref > PROTO_CURRENT_REF_MTPA || !cc_kind_known(c.current_ctrl) ||
        !angle_src_known(c.angle_src) || c.capture_pre >= CAPTURE_LEN ||
        c.speed_kp_a_per_rad_s < 0.0f || c.speed_ki_a_per_rad < 0.0f || c.identify > 1u ||
        c.predictor > PROTO_ESTIMATOR_NLMS_ADALINE || (c.identify != 0u && c.id_window < 2u) ||
        !(c.pred_scale_l_d > 0.0f) || !(c.pred_scale_l_q > 0.0f) || !(c.pred_scale_psi_f >= 0.0f) ||
        !(c.pred_scale_r_s >= 0.0f) ||
        !(c.pred_scale_l_d <= 100.0f && c.pred_scale_l_q <= 100.0f &&
          c.pred_scale_psi_f <= 100.0f && c.pred_scale_r_s <= 100.0f) ||
        c.mpcc_candidates > PROTO_MPCC_CANDIDATES_ADJACENT ||
        !within(c.foc_bw_rad_s, 0.0f, 0.5f / c.ts_s) ||
        !within(c.est_bw_rad_s, 0.0f, 0.5f / c.ts_s) ||
        !within(c.est_min_speed_rpm, 0.0f, FW_SPEED_TRIP_MAX_RPM) ||
        !within(c.est_lock_timeout_s, 0.0f, FW_HEARTBEAT_MAX_S) ||
        !within(c.est_theta0_rad, -7.0f, 7.0f)) {
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
    if (!within(s.duration_s, 0.0f, PROFILE_SEGMENT_MAX_S) ||
        !within(s.speed_rpm, -FW_SPEED_TRIP_MAX_RPM, FW_SPEED_TRIP_MAX_RPM) ||
        !within(s.ramp_rpm_s, 0.0f, 1e7f) || !within(s.load_nm, -FW_LOAD_MAX_NM, FW_LOAD_MAX_NM) ||
        !within(s.inject_hz, 0.0f, 1e4f) || !finite_f(s.inject_a)) {
        return PROTO_ACK_STATUS_BAD_VALUE; /* NaN, infinite or beyond any motor */
    }
    if (f->have_motor && !(fabsf(s.speed_rpm) <= f->motor.speed_max_rpm)) {
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
    if ((s.flags & PROTO_SEGMENT_FLAG_CC_FOC) != 0u &&
        (s.flags & PROTO_SEGMENT_FLAG_CC_MPCC) != 0u) {
        return PROTO_ACK_STATUS_BAD_VALUE; /* one current controller per segment */
    }
    if (s.kind > PROFILE_KIND_COMMISSION || !(s.inject_hz >= 0.0f) ||
        !(fabsf(s.inject_a) <= 1e3f) ||
        (s.kind == PROFILE_KIND_IDENTIFY_R && (s.speed_rpm != 0.0f || !(s.inject_a != 0.0f)))) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (f->have_motor && fabsf(s.inject_a) > f->motor.i_max_a) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    return profile_set(&f->prof, s.index, &seg) ? PROTO_ACK_STATUS_OK : PROTO_ACK_STATUS_BAD_VALUE;
}

static uint16_t cmd_config_calib(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_config_calib_t c;
    if (!proto_config_calib_unpack(&c, p, n)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    /* offsets within 10 A, gain errors within 20 % (a sensor beyond is broken, not calibrated) */
    if (!within(c.i_a_offset_a, -10.0f, 10.0f) || !within(c.i_b_offset_a, -10.0f, 10.0f) ||
        !within(c.i_c_offset_a, -10.0f, 10.0f) || !within(c.i_a_gain_err, -0.2f, 0.2f) ||
        !within(c.i_b_gain_err, -0.2f, 0.2f) || !within(c.i_c_gain_err, -0.2f, 0.2f)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    f->calib = c;
    f->have_calib = c.i_a_offset_a != 0.0f || c.i_b_offset_a != 0.0f || c.i_c_offset_a != 0.0f ||
                    c.i_a_gain_err != 0.0f || c.i_b_gain_err != 0.0f || c.i_c_gain_err != 0.0f;
    return PROTO_ACK_STATUS_OK;
}

static uint16_t cmd_config_commission(fw_t *f, const uint16_t *p, uint16_t n)
{
    proto_config_commission_t c;
    if (!proto_config_commission_unpack(&c, p, n)) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    if ((c.steps & ~((1u << COMM_N_STEPS) - 1u)) != 0u || !(c.i_test_a > 0.0f) ||
        !(c.spin_rpm >= 0.0f && c.spin_rpm <= FW_SPEED_TRIP_MAX_RPM) ||
        (f->have_motor && (c.i_test_a > f->motor.i_max_a || c.spin_rpm > f->motor.speed_max_rpm))) {
        return PROTO_ACK_STATUS_BAD_VALUE;
    }
    f->comm_cfg = c;
    return PROTO_ACK_STATUS_OK;
}

static void handle_frame(fw_t *f, uint16_t id, uint16_t seq, const uint16_t *p, uint16_t n)
{
    uint16_t st = PROTO_ACK_STATUS_OK;
    f->link.rx_frames++;
    switch (id) {
    case PROTO_ID_HELLO:
        fw_send_identify(f);
        return;
    case PROTO_ID_HEARTBEAT:
        f->hb_isr = f->isr_count;
        return;
    case PROTO_ID_CAPTURE_READ: {
        proto_capture_read_t r;
        if (proto_capture_read_unpack(&r, p, n)) {
            fw_send_capture_chunk(f, r.offset);
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
    case PROTO_ID_CONFIG_CALIB:
        st = cmd_config_calib(f, p, n);
        break;
    case PROTO_ID_CONFIG_COMMISSION:
        st = cmd_config_commission(f, p, n);
        break;
    case PROTO_ID_CONFIG_SENSORLESS:
        st = cmd_config_sensorless(f, p, n);
        break;
    case PROTO_ID_GAMMA_NODE:
        st = cmd_gamma_node(f, p, n);
        break;
    case PROTO_ID_START:
        st = fw_start_run(f);
        if (st == PROTO_ACK_STATUS_OK) {
            fw_send_ack(f, id, seq, st);
            fw_raise(f, PROTO_EVENT_STARTED, 0);
            fw_flush(f);
            return;
        }
        break;
    case PROTO_ID_STOP:
        if (f->state == PROTO_STATE_RUNNING) {
            fw_enter_stopping(f, PROTO_STOP_REASON_HOST_STOP);
        } else if (!fw_active(f)) {
            st = PROTO_ACK_STATUS_OK; /* already stopped: idempotent */
        }
        break;
    case PROTO_ID_STOP_AT: { /* for the run about to start or running; cleared at its end */
        proto_stop_at_t a;
        if (proto_stop_at_unpack(&a, p, n)) {
            f->stop_at_tick = a.tick;
        } else {
            st = PROTO_ACK_STATUS_BAD_VALUE;
        }
        break;
    }
    case PROTO_ID_ABORT:
        if (fw_active(f)) {
            fw_pwm_off(f, PROTO_STATE_IDLE, PROTO_STOP_REASON_ABORT);
        }
        break;
    default:
        st = f->board_msg != 0 ? f->board_msg(f->board_ctx, id, p, n) : PROTO_ACK_STATUS_UNKNOWN;
        break;
    }
    fw_flush(
        f); /* what the command raised (abort: the stopped event and status) precedes its ack */
    fw_send_ack(f, id, seq, st);
}

void fw_can_rx(fw_t *f, uint16_t id, const uint16_t *data, uint16_t dlc)
{
    int16_t r = can_link_rx(&f->link.can, id, data, dlc);
    if (r == CAN_RX_MSG) {
        f->link.link = f->link.can.msg_id == PROTO_ID_HELLO ? FW_LINK_CAN : f->link.link;
        handle_frame(f, f->link.can.msg_id, f->link.can.seq, f->link.can.payload,
                     f->link.can.payload_len);
    } else if (r < 0) {
        f->link.rx_bad++;
    }
}

void fw_rx_octet(fw_t *f, uint16_t octet)
{
    int16_t r = frame_parser_push(&f->link.rx, octet);
    if (r == FRAME_OK) {
        f->link.link = f->link.rx.msg_id == PROTO_ID_HELLO ? FW_LINK_SERIAL : f->link.link;
        handle_frame(f, f->link.rx.msg_id, f->link.rx.seq, f->link.rx.payload,
                     f->link.rx.payload_len);
    } else if (r < 0) {
        f->link.rx_bad++;
    }
}

bool fw_tx_pop(fw_t *f, uint16_t *octet)
{
    return txq_pop(&f->link.tx, octet);
}

uint16_t fw_tx_pop_n(fw_t *f, uint16_t *out, uint16_t max)
{
    return txq_pop_n(&f->link.tx, out, max);
}
