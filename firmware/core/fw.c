/* The firmware application: state, faults, heartbeat, and the control period as a pipeline of
 * stages (fw.h, docs/architecture.md). Host commands are in fw_cmd.c, messages to the host in
 * fw_msg.c; the stages only raise events, which fw_flush sends at the end of the period. */
#include "fw_internal.h"
#include "transforms.h"

#include <math.h>
#include <string.h>

/* ------------------------------------------------------------------ accessors */

void fw_set_board_hook(fw_t *f, fw_board_msg_fn fn, void *ctx)
{
    f->board_msg = fn;
    f->board_ctx = ctx;
}

bool fw_active(const fw_t *f)
{
    return f->state == PROTO_STATE_RUNNING || f->state == PROTO_STATE_STOPPING;
}

uint32_t fw_tick(const fw_t *f)
{
    return f->tick;
}
uint32_t fw_isr_count(const fw_t *f)
{
    return f->isr_count;
}
uint32_t fw_heartbeat_isr(const fw_t *f)
{
    return f->hb_isr;
}
uint16_t fw_state(const fw_t *f)
{
    return f->state;
}
uint32_t fw_tx_dropped(const fw_t *f)
{
    return f->link.tx.dropped;
}
uint16_t fw_tx_level(const fw_t *f)
{
    return f->link.tx.level;
}
can_link_t *fw_can(fw_t *f)
{
    return &f->link.can;
}
uint16_t fw_can_tx_level(const fw_t *f)
{
    return can_link_tx_level(&f->link.can);
}

uint16_t fw_segment(const fw_t *f, bool *begun)
{
    *begun = f->prof.begun;
    return f->prof.index;
}

const proto_config_ctrl_t *fw_ctrl(const fw_t *f)
{
    return f->have_ctrl ? &f->ctrl : NULL;
}

/* ------------------------------------------------------------------ state changes */

void fw_raise(fw_t *f, uint16_t code, int32_t arg)
{
    (void)evq_push(&f->events, f->tick, code, arg);
}

void fw_enter_stopping(fw_t *f, uint16_t reason)
{
    if (f->state == PROTO_STATE_RUNNING) {
        f->state = PROTO_STATE_STOPPING;
        f->stop_reason = reason;
        ramp_reset(&f->stop.ramp, f->sig.speed_ref_rpm);
        f->stop.ticks = 0u;
        f->stop.hold_ticks = 0u;
        f->stop.hold_sum_rpm = 0.0f;
    }
}

void fw_pwm_off(fw_t *f, uint16_t new_state, uint16_t reason)
{
    f->stop_at_tick = 0u; /* a stop_at belongs to the run that ends here */
    f->state = new_state;
    f->stop_reason = reason;
    fw_raise(f, PROTO_EVENT_STOPPED, (int32_t)reason);
    f->status_due = true;
}

void fw_trip(fw_t *f, uint16_t fault_bits)
{
    f->faults = (uint16_t)(f->faults | fault_bits);
    fw_raise(f, PROTO_EVENT_FAULT, (int32_t)fault_bits);
    if (capture_freeze(&f->cap)) { /* the whole buffer leads up to the fault */
        fw_raise(f, PROTO_EVENT_CAPTURE_TRIGGERED, -1);
    }
    fw_pwm_off(f, PROTO_STATE_FAULT, PROTO_STOP_REASON_FAULT);
}

/* ------------------------------------------------------------------ supervision */

static void check_faults(fw_t *f, const fw_meas_t *m)
{
    uint16_t bits = 0u;
    float it = f->limits.i_trip_a;
    /* written as "not within", so that a non-finite measurement (NaN) trips too */
    if (!(fabsf(m->i_a_a) <= it) || !(fabsf(m->i_b_a) <= it) || !(fabsf(m->i_c_a) <= it)) {
        bits |= PROTO_FAULT_OVER_CURRENT;
    }
    if (!(fabsf(f->ang.speed_rpm) <= f->limits.speed_trip_rpm)) {
        bits |= PROTO_FAULT_OVER_SPEED;
    }
    if (!(m->v_dc_v >= f->limits.v_dc_min_v)) {
        bits |= PROTO_FAULT_DC_UNDER_VOLTAGE;
    }
    if (!(m->v_dc_v <= f->limits.v_dc_max_v)) {
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
        fw_raise(f, PROTO_EVENT_HEARTBEAT_LOST, (int32_t)(age_s * 1000.0f));
        fw_enter_stopping(f, PROTO_STOP_REASON_HEARTBEAT_LOST);
    }
}

/* End of a stop: the reference at zero and the rotor still, or too long. Still: the speed's mean
 * over a window of FW_STOP_HOLD_S below FW_STOP_SPEED_RPM. Not every sample: an encoder's speed at
 * standstill toggles by about a count per observer time constant (+-3.5 r/min on a 2048-line
 * encoder), so a per-sample test ran into the timeout; the mean over the window is the rotor's
 * position change over it. A window whose mean is too high starts the next one. */
static bool stop_finished(fw_t *f)
{
    if (f->state != PROTO_STATE_STOPPING) {
        return false;
    }
    f->stop.ticks++;
    if (f->stop.ramp.out_rpm == 0.0f) {
        f->stop.hold_ticks++;
        f->stop.hold_sum_rpm += f->ang.speed_rpm;
    } else {
        f->stop.hold_ticks = 0u;
        f->stop.hold_sum_rpm = 0.0f;
    }
    if ((float)f->stop.hold_ticks * f->ctrl.ts_s >= FW_STOP_HOLD_S) {
        if (fabsf(f->stop.hold_sum_rpm) < FW_STOP_SPEED_RPM * (float)f->stop.hold_ticks) {
            return true;
        }
        f->stop.hold_ticks = 0u; /* still turning (or a NaN speed): the next window */
        f->stop.hold_sum_rpm = 0.0f;
    }
    return (float)f->stop.ticks * f->ctrl.ts_s >= FW_STOP_TIMEOUT_S;
}

/* ------------------------------------------------------------------ the stages */

/* Measure: the encoder's reading (its observer starts where the rotor is), logged as truth. */
static void stage_measure(fw_t *f, const fw_meas_t *m)
{
    if (f->tick == 0u) {
        enc_reset(&f->enc, m->enc_count);
    }
    enc_step(&f->enc, m->enc_count, &f->enc_out);
    f->sig.theta_e_rad = f->enc_out.theta_e_rad;
    f->sig.speed_rpm = f->enc_out.speed_rpm;
}

/* Angle slot: the angle and speed the control uses. */
static void stage_angle(fw_t *f, float i_al, float i_be)
{
    angle_in_t ai;
    ai.enc = &f->enc_out;
    ai.i_alpha_a = i_al;
    ai.i_beta_a = i_be;
    ai.u_alpha_prev_v = f->cc_out.u_alpha_v;
    ai.u_beta_prev_v = f->cc_out.u_beta_v;
    ai.u_d_prev_v = f->cc_out.u_d_avg_v;
    ai.u_q_prev_v = f->cc_out.u_q_avg_v;
    ai.i_d_pred_a = f->cc_out.i_d_pred_a;
    ai.i_q_pred_a = f->cc_out.i_q_pred_a;
    ai.omega_ref_e_rad_s =
        f->sig.speed_ref_rpm * (float)f->motor.pole_pairs * (1.0f / FW_RPM_PER_RAD_S);
    if (!angle_src_is_estimator(f->ctrl.angle_src)) {
        angle_step(&f->angle, &ai, &f->ang);
        f->est = f->ang;
        f->sig.theta_e_est_rad = f->ang.theta_e_rad;
        f->sig.speed_est_rpm = f->ang.speed_rpm;
        f->sig.omega_e_rad_s = f->ang.omega_e_rad_s;
        return;
    }
    /* an estimator: it runs every period; its angle closes the loop unless the segment asks for
     * the encoder. The telemetry's estimate is always the estimator's. */
    angle_step(&f->angle, &ai, &f->est);
    if (f->seg_angle_encoder) {
        angle_encoder_out(&ai, &f->ang);
    } else {
        f->ang = f->est;
    }
    f->sig.theta_e_est_rad = f->est.theta_e_rad;
    f->sig.speed_est_rpm = f->est.speed_rpm;
    if (f->est.if_event_now != 0u) {
        const float v = f->est.speed_rpm;
        fw_raise(f, f->est.if_event_now, (v == v && fabsf(v) < 1e6f) ? (int32_t)(v * 10.0f) : 0);
    }
    if (f->est.pol_result_now != 0u) {
        fw_raise(f, PROTO_EVENT_POLARITY, (int32_t)f->est.pol_result_now);
        fw_raise(f, PROTO_EVENT_POLARITY_ASYM, (int32_t)(f->est.pol_asym * 10000.0f));
    }
    f->sig.omega_e_rad_s = f->ang.omega_e_rad_s;
}

/* Loss of lock: the estimator closing the loop out of lock for est_lock_timeout_s trips the
 * lost_lock fault (PWM off at once). While stopping, its loss ends the stop at once instead: PWM
 * off, the rotor coasts (the estimator cannot brake it below its speed range). */
static void check_lock(fw_t *f)
{
    if (!angle_src_is_estimator(f->ctrl.angle_src) || f->seg_angle_encoder || f->est.locked) {
        f->unlock_ticks = 0u;
        return;
    }
    f->unlock_ticks++;
    if (f->state == PROTO_STATE_STOPPING) { /* no reason to wait: coast at once */
        fw_pwm_off(f,
                   f->stop_reason == PROTO_STOP_REASON_PROFILE_END ? PROTO_STATE_DONE
                                                                   : PROTO_STATE_IDLE,
                   f->stop_reason);
        return;
    }
    if ((float)f->unlock_ticks * f->ctrl.ts_s < f->ctrl.est_lock_timeout_s) {
        return;
    }
    if (f->state == PROTO_STATE_RUNNING) {
        fw_trip(f, PROTO_FAULT_LOST_LOCK);
    }
}

/* Capture: the sample with the switch state applied while it was taken (encoder angle). */
static void stage_capture(fw_t *f, const fw_meas_t *m)
{
    capture_sample_t cs;
    cs.i_a_a = m->i_a_a;
    cs.i_b_a = m->i_b_a;
    cs.i_c_a = m->i_c_a;
    cs.s_abc = cc_applied_code(&f->cc);
    cs.v_dc_v = m->v_dc_v;
    cs.theta_e_rad = f->sig.theta_e_rad;
    cs.omega_e_rad_s = f->enc_out.omega_e_rad_s;
    capture_record(&f->cap, f->tick, &cs);
}

/* Commissioning (comm.h): the sequence's configuration from config_commission, or defaults. */
static void start_commission(fw_t *f)
{
    comm_cfg_t cc;
    const proto_config_commission_t *k = &f->comm_cfg;
    cc.steps = k->steps != 0u ? k->steps : (uint16_t)((1u << COMM_N_STEPS) - 1u);
    cc.i_test_a = k->i_test_a > 0.0f ? k->i_test_a : 0.5f * f->motor.i_max_a;
    cc.spin_rpm = k->spin_rpm > 0.0f ? k->spin_rpm : 0.5f * f->motor.speed_max_rpm;
    cc.ts_s = f->ctrl.ts_s;
    cc.v_dc_min_v = f->limits.v_dc_min_v;
    cc.v_dc_max_v = f->limits.v_dc_max_v;
    cc.motor = f->motor;
    cc.i_dt_nom_a = f->ctrl.i_dt_a;
    cc.v_drop_nom_v = f->ctrl.v_drop_v;
    cc.enc_counts = f->ctrl.enc_counts;
    comm_start(&f->comm, &cc);
}

/* References: the profile (or the stop ramp) gives speed and load; the segment its kind. */
static void stage_profile(fw_t *f, float *speed_ref_rpm, float *load_nm)
{
    if (f->state == PROTO_STATE_RUNNING) {
        profile_out_t po;
        profile_step(&f->prof, f->ctrl.ts_s, &po);
        if (po.segment_started) {
            fw_raise(f, PROTO_EVENT_SEGMENT_START, (int32_t)po.index);
            f->commissioning = po.kind == PROFILE_KIND_COMMISSION;
            if (f->commissioning) {
                start_commission(f);
            }
            if ((po.flags & PROFILE_FLAG_CAPTURE) != 0u && capture_trigger(&f->cap)) {
                fw_raise(f, PROTO_EVENT_CAPTURE_TRIGGERED, (int32_t)po.index);
            }
        }
        if (po.finished) {
            fw_raise(f, PROTO_EVENT_PROFILE_DONE, (int32_t)po.index);
            fw_enter_stopping(f, PROTO_STOP_REASON_PROFILE_END);
        } else {
            *speed_ref_rpm = po.speed_ref_rpm;
            *load_nm = po.load_nm;
            f->seg.identify_r = po.kind == PROFILE_KIND_IDENTIFY_R;
            f->seg.hold = (po.flags & PROFILE_FLAG_HOLD_EST) != 0u;
            f->seg.inject_a = po.inject_a;
            f->seg.inject_hz = po.inject_hz;
            f->seg.tick = po.tick_in_seg;
            f->seg.ticks = po.seg_ticks;
            f->seg_angle_encoder = (po.flags & PROTO_SEGMENT_FLAG_ANGLE_ENCODER) != 0u;
            f->cc_want = cc_segment_kind(po.flags, f->cc_want);
            return;
        }
    }
    f->seg.identify_r = false;
    f->seg.hold = true; /* no identification while stopping */
    f->seg.inject_a = 0.0f;
    /* stopping: quick-stop ramp to zero, load released */
    *speed_ref_rpm = ramp_step(&f->stop.ramp, 0.0f);
    *load_nm = 0.0f;
}

/* Speed loop and current references (identify_r: off, the d axis carries the injection and the
 * q axis nothing). */
static void stage_current_refs(fw_t *f, float speed_ref_rpm)
{
    fw_dq_t idq_ref;
    f->speed_div_count++;
    const bool est_in_loop = angle_src_is_estimator(f->ctrl.angle_src) && !f->seg_angle_encoder;
    if (f->seg.identify_r || (est_in_loop && f->est.hold_refs)) {
        /* held: i_q* = 0, or what an I/f start hands the speed loop (if_start.h) */
        const float i_q_hold = f->seg.identify_r ? 0.0f : f->est.i_q_hold_a;
        speed_pi_reset(&f->spi, i_q_hold);
        f->i_s_ref_a = i_q_hold;
        f->i_d_base_a = 0.0f;
        f->sig.i_q_ref_a = i_q_hold;
    } else if (f->speed_div_count >= f->ctrl.speed_div) {
        fw_motor_t m = f->motor;
        cc_params_t p;
        if (ident_converged_params(&f->ident, &p)) { /* MTPA on the identified machine */
            m.l_d_h = p.l_d_h;
            m.l_q_h = p.l_q_h;
            m.psi_f_wb = p.psi_f_wb;
        }
        f->speed_div_count = 0u;
        f->i_s_ref_a =
            speed_pi_step(&f->spi, speed_ref_rpm / FW_RPM_PER_RAD_S, f->ang.omega_m_rad_s);
        mtpa_split(&m, f->ctrl.current_ref, f->i_s_ref_a, &idq_ref);
        f->i_d_base_a = idq_ref.d;
        f->sig.i_q_ref_a = idq_ref.q;
    }
    f->sig.i_d_ref_a = ident_d_ref(&f->ident, &f->seg, f->i_d_base_a);
    if (est_in_loop) { /* the sensorless start's pulses, or the estimator's excitation at rest */
        f->sig.i_d_ref_a += f->est.i_d_inject_a;
    }
}

/* Current-control slot, with the q-current dither and the identification's predictor feed. */
static void stage_current_control(fw_t *f, const fw_meas_t *m, float c, float s)
{
    cc_in_t ci;
    cc_params_t p;
    /* the dither's step: one vector's current step on L_q (the identified one once converged) */
    const float l_q = ident_converged_params(&f->ident, &p) ? p.l_q_h : f->motor.l_q_h;
    ci.i_d_a = f->sig.i_d_a;
    ci.i_q_a = f->sig.i_q_a;
    ci.i_d_ref_a = f->sig.i_d_ref_a;
    ci.i_q_ref_a = f->sig.i_q_ref_a;
    if (!cc_uses_duties(&f->cc)) { /* the finite-control-set dither; a modulator needs none */
        ci.i_q_ref_a += dither_step(&f->dither, 0.6666667f * m->v_dc_v * f->ctrl.ts_s / l_q);
    }
    ci.theta_e_rad = f->ang.theta_e_rad;
    ci.cos_theta = c;
    ci.sin_theta = s;
    ci.omega_e_rad_s = f->ang.omega_e_rad_s;
    ci.v_dc_v = m->v_dc_v;
    ident_predictor(&f->ident, &ci.pred);
    if (f->cc_want != f->cc.kind) { /* a segment names another current controller */
        cc_hand_over(&f->cc, &f->cc_cfg, f->cc_want, &ci, f->u_d_mean_v, f->u_q_mean_v);
    }
    cc_step(&f->cc, &ci, &f->cc_out);
    {
        const float a = f->ctrl.ts_s * (1.0f / FW_CC_MEAN_TAU_S);
        f->u_d_mean_v += a * (f->cc_out.u_d_avg_v - f->u_d_mean_v);
        f->u_q_mean_v += a * (f->cc_out.u_q_avg_v - f->u_q_mean_v);
    }
    f->sig.u_d_v = f->cc_out.u_d_v;
    f->sig.u_q_v = f->cc_out.u_q_v;
}

/* Modulation: what the board applies from the next period on. */
static void stage_modulation(const fw_t *f, float load_nm, fw_cmd_t *cmd)
{
    const cc_out_t *o = &f->cc_out;
    cmd->mode = o->mode == CC_OUT_DUTIES ? FW_CMD_DUTIES : FW_CMD_STATES;
    cmd->s_a = o->s_a;
    cmd->s_b = o->s_b;
    cmd->s_c = o->s_c;
    cmd->duty_a = o->duty_a;
    cmd->duty_b = o->duty_b;
    cmd->duty_c = o->duty_c;
    cmd->pwm_on = true;
    cmd->load_nm = load_nm;
}

/* Estimators: the identification sees the period's currents and applied voltage. */
static void stage_estimators(fw_t *f, const fw_meas_t *m)
{
    ident_in_t ii;
    ident_out_t io;
    ii.i_d_a = f->sig.i_d_a;
    ii.i_q_a = f->sig.i_q_a;
    ii.u_d_avg_v = f->cc_out.u_d_avg_v;
    ii.u_q_avg_v = f->cc_out.u_q_avg_v;
    ii.theta_e_rad = f->ang.theta_e_rad;
    ii.omega_e_rad_s = f->ang.omega_e_rad_s;
    ii.i_a_a = m->i_a_a;
    ii.i_b_a = m->i_b_a;
    ii.i_c_a = m->i_c_a;
    ii.i_d_ref_a = f->sig.i_d_ref_a;
    ident_step(&f->ident, &f->seg, &ii, &io);
    if (io.r_identified_now) {
        fw_raise(f, PROTO_EVENT_R_IDENTIFIED, (int32_t)(io.r_s_ohm * 1000.0f + 0.5f));
    }
}

static void cmd_safe(fw_cmd_t *cmd)
{
    cmd->mode = FW_CMD_STATES;
    cmd->pwm_on = false;
    cmd->s_a = 0u;
    cmd->s_b = 0u;
    cmd->s_c = 0u;
    cmd->duty_a = 0.0f;
    cmd->duty_b = 0.0f;
    cmd->duty_c = 0.0f;
    cmd->load_nm = 0.0f;
}

/* The commissioning sequence in place of the control stages (PWM off at its end or failure). */
static void stage_commission(fw_t *f, const fw_meas_t *m, fw_cmd_t *cmd)
{
    comm_in_t ci;
    comm_out_t co;
    comm_t *c = &f->comm;
    ci.i_a_a = m->i_a_a;
    ci.i_b_a = m->i_b_a;
    ci.i_c_a = m->i_c_a;
    ci.v_dc_v = m->v_dc_v;
    ci.theta_enc_rad = f->enc_out.theta_e_rad;
    ci.omega_e_rad_s = f->enc_out.omega_e_rad_s;
    if (f->state == PROTO_STATE_STOPPING) {
        if (comm_brake(c, &ci, &co)) {
            fw_pwm_off(f,
                       f->stop_reason == PROTO_STOP_REASON_PROFILE_END ? PROTO_STATE_DONE
                                                                       : PROTO_STATE_IDLE,
                       f->stop_reason);
            return;
        }
    } else {
        uint16_t st = comm_step(c, &ci, &co);
        if (c->step_started) {
            c->step_started = false;
            fw_raise(f, PROTO_EVENT_COMMISSION_STEP, (int32_t)c->step);
        }
        if (st == COMM_FAILED) {
            fw_raise(f, PROTO_EVENT_COMMISSION_FAILED,
                     (int32_t)(((uint32_t)c->step << 8) | c->fail_reason));
            fw_pwm_off(f, PROTO_STATE_IDLE, PROTO_STOP_REASON_COMMISSION_FAILED);
            return;
        }
        if (st == COMM_DONE) {
            fw_raise(f, PROTO_EVENT_PROFILE_DONE, (int32_t)f->prof.index);
            fw_pwm_off(f, PROTO_STATE_DONE, PROTO_STOP_REASON_PROFILE_END);
            return;
        }
    }
    f->sig.i_d_a = co.i_d_a;
    f->sig.i_q_a = co.i_q_a;
    f->sig.i_d_ref_a = co.i_d_ref_a;
    f->sig.i_q_ref_a = co.i_q_ref_a;
    f->sig.u_d_v = co.u_d_v;
    f->sig.u_q_v = co.u_q_v;
    f->sig.speed_ref_rpm = co.speed_ref_rpm;
    f->sig.load_nm = 0.0f;
    cmd->mode = FW_CMD_DUTIES;
    cmd->duty_a = co.duty[0];
    cmd->duty_b = co.duty[1];
    cmd->duty_c = co.duty[2];
    cmd->pwm_on = co.pwm_on;
    cmd->load_nm = 0.0f;
}

/* One control period of an active run. */
static void period(fw_t *f, const fw_meas_t *m, fw_cmd_t *cmd)
{
    float speed_ref_rpm = 0.0f, load_nm = 0.0f, c, s, i_al, i_be;

    stage_measure(f, m);
    i_al = m->i_a_a;
    i_be = (m->i_a_a + 2.0f * m->i_b_a) * 0.57735026918963f;
    stage_angle(f, i_al, i_be);
    c = cosf(f->ang.theta_e_rad);
    s = sinf(f->ang.theta_e_rad);
    f->sig.i_d_a = c * i_al + s * i_be;
    f->sig.i_q_a = -s * i_al + c * i_be;
    stage_capture(f, m);

    check_faults(f, m);
    if (fw_active(f)) {
        check_lock(f);
    }
    if (fw_active(f)) {
        check_heartbeat(f);
        if (f->stop_at_tick != 0u && f->tick >= f->stop_at_tick) {
            fw_enter_stopping(f, PROTO_STOP_REASON_HOST_STOP); /* stop_at: as a host stop */
        }
        stage_profile(f, &speed_ref_rpm, &load_nm);
    }
    if (!fw_active(f)) { /* a fault, or the profile's end */
        fw_send_telemetry(f);
        f->tick++;
        return;
    }
    if (f->commissioning) {
        stage_commission(f, m, cmd);
        fw_send_telemetry(f);
        f->tick++;
        return;
    }
    f->sig.speed_ref_rpm = speed_ref_rpm;
    f->sig.load_nm = load_nm;
    stage_current_refs(f, speed_ref_rpm);
    stage_current_control(f, m, c, s);
    stage_estimators(f, m);
    stage_modulation(f, load_nm, cmd);

    fw_send_telemetry(f);
    f->tick++;
    if (stop_finished(f)) {
        cmd->pwm_on = false;
        fw_pwm_off(f,
                   f->stop_reason == PROTO_STOP_REASON_PROFILE_END ? PROTO_STATE_DONE
                                                                   : PROTO_STATE_IDLE,
                   f->stop_reason);
    }
}

void fw_isr(fw_t *f, const fw_meas_t *m, fw_cmd_t *cmd)
{
    fw_meas_t mc;
    f->isr_count++;
    f->sig.v_dc_v = m->v_dc_v;
    cmd_safe(cmd);
    if (!fw_active(f)) {
        return;
    }
    if (f->have_calib) { /* current-sensor calibration from commissioning (config_calib) */
        mc = *m;
        mc.i_a_a = (m->i_a_a - f->calib.i_a_offset_a) / (1.0f + f->calib.i_a_gain_err);
        mc.i_b_a = (m->i_b_a - f->calib.i_b_offset_a) / (1.0f + f->calib.i_b_gain_err);
        mc.i_c_a = (m->i_c_a - f->calib.i_c_offset_a) / (1.0f + f->calib.i_c_gain_err);
        m = &mc;
    }
    period(f, m, cmd);
    fw_flush(f);
}

void fw_init(fw_t *f, const fw_cfg_t *cfg)
{
    memset(f, 0, sizeof(*f));
    f->cfg = *cfg;
    frame_parser_init(&f->link.rx);
    can_link_init(&f->link.can, cfg->can_node);
    txq_init(&f->link.tx);
    capture_init(&f->cap, 0u);
    evq_init(&f->events);
    f->state = PROTO_STATE_IDLE;
}
