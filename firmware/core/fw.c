/* The firmware application: state, faults, heartbeat, the profile reference and the control
 * period (fw.h). Host commands are in fw_cmd.c, messages to the host in fw_msg.c, identification
 * in fw_ident.c. */
#include "fw_internal.h"
#include "transforms.h"

#include <math.h>
#include <string.h>

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

void fw_enter_stopping(fw_t *f, uint16_t reason)
{
    if (f->state == PROTO_STATE_RUNNING) {
        f->state = PROTO_STATE_STOPPING;
        f->stop_reason = reason;
        ramp_reset(&f->stop_ramp, f->sig.speed_ref_rpm);
        f->stop_ticks = 0u;
        f->stop_hold_ticks = 0u;
    }
}

void fw_pwm_off(fw_t *f, uint16_t new_state, uint16_t reason)
{
    f->state = new_state;
    f->stop_reason = reason;
    fw_send_event(f, PROTO_EVENT_STOPPED, (int32_t)reason);
    fw_send_status(f);
}

void fw_trip(fw_t *f, uint16_t fault_bits)
{
    f->faults = (uint16_t)(f->faults | fault_bits);
    fw_send_event(f, PROTO_EVENT_FAULT, (int32_t)fault_bits);
    if (capture_freeze(&f->cap)) {   /* the whole buffer leads up to the fault */
        fw_send_event(f, PROTO_EVENT_CAPTURE_TRIGGERED, -1);
    }
    fw_pwm_off(f, PROTO_STATE_FAULT, FW_STOP_FAULT);
}


uint16_t fw_start_run(fw_t *f)
{
    mpcc_cfg_t mc;
    speed_pi_cfg_t sc;
    enc_cfg_t ec;
    dither_cfg_t dc;
    ramp_cfg_t sr;
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

    fw_ident_init(f);
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
    sr.rate_rpm_s = FW_STOP_RAMP_RPM_S;
    sr.ts_s = f->ctrl.ts_s;
    ramp_init(&f->stop_ramp, &sr);
    return PROTO_ACK_STATUS_OK;
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
        fw_trip(f, bits);
    }
}

static void check_heartbeat(fw_t *f)
{
    float age_s = (float)(f->isr_count - f->hb_isr) * f->ctrl.ts_s;
    if (!f->hb_lost && age_s > f->ctrl.heartbeat_timeout_s) {
        f->hb_lost = true;
        f->faults = (uint16_t)(f->faults | PROTO_FAULT_HEARTBEAT);
        fw_send_event(f, PROTO_EVENT_HEARTBEAT_LOST, (int32_t)(age_s * 1000.0f));
        fw_enter_stopping(f, FW_STOP_HEARTBEAT);
    }
}

/* Speed reference and load for this period, from the profile or the stop ramp. */
static void reference(fw_t *f, float *speed_ref_rpm, float *load_nm)
{
    if (f->state == PROTO_STATE_RUNNING) {
        profile_out_t po;
        profile_step(&f->prof, f->ctrl.ts_s, &po);
        if (po.segment_started) {
            fw_send_event(f, PROTO_EVENT_SEGMENT_START, (int32_t)po.index);
            if ((po.flags & PROFILE_FLAG_CAPTURE) != 0u && capture_trigger(&f->cap)) {
                fw_send_event(f, PROTO_EVENT_CAPTURE_TRIGGERED, (int32_t)po.index);
            }
        }
        if (po.finished) {
            fw_send_event(f, PROTO_EVENT_PROFILE_DONE, (int32_t)po.index);
            fw_enter_stopping(f, FW_STOP_PROFILE_END);
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
    *speed_ref_rpm = ramp_step(&f->stop_ramp, 0.0f);
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
        fw_send_telemetry(f);
        f->tick++;
        return;
    }
    check_heartbeat(f);

    reference(f, &speed_ref_rpm, &load_nm);
    if (!fw_active(f)) {   /* reference() may end the run */
        fw_send_telemetry(f);
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
    f->sig.i_d_ref_a = fw_d_current_ref(f);

    /* current control slot: MPCC */
    mi.i_d_a = f->sig.i_d_a;
    mi.i_q_a = f->sig.i_q_a;
    mi.i_d_ref_a = f->sig.i_d_ref_a;
    mi.i_q_ref_a = f->sig.i_q_ref_a +
                   dither_step(&f->dither, 0.6666667f * m->v_dc_v * f->ctrl.ts_s / f->motor.l_q_h);
    mi.theta_e_rad = f->sig.theta_e_est_rad;
    mi.omega_e_rad_s = f->enc_out.omega_e_rad_s;
    mi.v_dc_v = m->v_dc_v;
    fw_predictor_params(f, &mi);
    mpcc_step_cs(&f->mpcc, &mi, c, s, &mo);   /* c, s: cos, sin of mi.theta_e_rad (above) */
    fw_ident_step(f, m, &mo);
    f->sig.u_d_v = mo.u_d_v;
    f->sig.u_q_v = mo.u_q_v;
    cmd->s_a = mo.s_a;
    cmd->s_b = mo.s_b;
    cmd->s_c = mo.s_c;
    cmd->pwm_on = true;
    cmd->load_nm = load_nm;

    fw_send_telemetry(f);
    f->tick++;

    /* end of a stop: reference at zero and the rotor (nearly) still for a while, or too long */
    if (f->state == PROTO_STATE_STOPPING) {
        f->stop_ticks++;
        if (f->stop_ramp.out_rpm == 0.0f && fabsf(f->enc_out.speed_rpm) < FW_STOP_SPEED_RPM) {
            f->stop_hold_ticks++;
        } else {
            f->stop_hold_ticks = 0u;
        }
    }
    if (f->state == PROTO_STATE_STOPPING &&
        ((float)f->stop_hold_ticks * f->ctrl.ts_s >= FW_STOP_HOLD_S ||
         (float)f->stop_ticks * f->ctrl.ts_s >= FW_STOP_TIMEOUT_S)) {
        cmd->pwm_on = false;
        fw_pwm_off(f, f->stop_reason == FW_STOP_PROFILE_END ? PROTO_STATE_DONE : PROTO_STATE_IDLE,
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

