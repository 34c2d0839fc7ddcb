/* The start of a run: every stage of the control period set up anew from the configuration
 * (fw.h, docs/architecture.md). Split from fw.c, which runs the period. */
#include "fw_internal.h"

#include <math.h>
#include <string.h>

static void init_stages(fw_t *f)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    cc_cfg_t cc;
    angle_cfg_t ac;
    speed_pi_cfg_t sc;
    enc_cfg_t ec;
    dither_cfg_t dc;
    ident_cfg_t ic;
    uint16_t i;

    ec.counts = c->enc_counts;
    ec.pole_pairs = f->motor.pole_pairs;
    ec.offset_e_rad = c->enc_offset_e_rad;
    ec.bw_rad_s = c->speed_obs_bw_rad_s;
    ec.ts_s = c->ts_s;
    enc_init(&f->enc, &ec);
    memset(&f->enc_out, 0, sizeof(f->enc_out));

    ac.src = c->angle_src;
    ac.pole_pairs = f->motor.pole_pairs;
    ac.ts_s = c->ts_s;
    ac.bw_rad_s = c->est_bw_rad_s;
    ac.min_speed_rpm = c->est_min_speed_rpm;
    ac.max_speed_rpm = f->limits.speed_trip_rpm;
    ac.theta0_rad = c->est_theta0_rad;
    ac.r_s_ohm = f->motor.r_s_ohm;
    ac.l_d_h = f->motor.l_d_h;
    ac.l_q_h = f->motor.l_q_h;
    ac.psi_f_wb = f->motor.psi_f_wb;
    ac.j_kgm2 = f->motor.j_kgm2;
    fw_snl_config(f, &f->snl_cfg);
    ac.snl = &f->snl_cfg;
    memset(&ac.ifs, 0, sizeof(ac.ifs));
    /* the MRAS's current-frequency start, when the first segment runs on the estimate (a start
     * on the encoder needs none) */
    if (f->have_snl && f->snl_msg.if_i_a > 0.0f &&
        !(f->prof.n_declared > 0u &&
          (f->prof.seg[0].flags & PROTO_SEGMENT_FLAG_ANGLE_ENCODER) != 0u)) {
        const float k = (float)f->motor.pole_pairs / FW_RPM_PER_RAD_S; /* r/min -> el. rad/s */
        ac.ifs.i_a = f->snl_msg.if_i_a;
        ac.ifs.accel_rad_s2 = f->snl_msg.if_accel_rpm_s * k;
        ac.ifs.handover_rad_s = f->snl_msg.if_handover_rpm * k;
        ac.ifs.align_s = FW_IFS_ALIGN_S;
        ac.ifs.settle_s = FW_IFS_SETTLE_S;
        ac.ifs.decay_s = FW_IFS_DECAY_S;
        ac.ifs.timeout_s = FW_IFS_TIMEOUT_S;
        ac.ifs.max_delta_rad = FW_IFS_MAX_DELTA_RAD;
    }
    angle_init(&f->angle, &ac);
    memset(&f->ang, 0, sizeof(f->ang));
    memset(&f->est, 0, sizeof(f->est));
    f->unlock_ticks = 0u;
    /* the first segment's choice holds from the first period on */
    f->seg_angle_encoder =
        f->prof.n_declared > 0u && (f->prof.seg[0].flags & PROTO_SEGMENT_FLAG_ANGLE_ENCODER) != 0u;

    sc.kp_a_per_rad_s = c->speed_kp_a_per_rad_s;
    sc.ki_a_per_rad = c->speed_ki_a_per_rad;
    sc.ts_s = c->ts_s * (float)c->speed_div;
    sc.out_max_a = f->motor.i_max_a;
    speed_pi_init(&f->spi, &sc);
    speed_pi_set_ref_weight(&f->spi, FW_SPEED_REF_WEIGHT);

    dc.period = FW_DITHER_PERIOD;
    dc.gain = FW_DITHER_GAIN;
    dither_init(&f->dither, &dc);

    cc.kind = cc_segment_kind(f->prof.n_declared > 0u ? f->prof.seg[0].flags : 0u, c->current_ctrl);
    mpcc_cfg_default(&cc.mpcc);
    cc.mpcc.ts_s = c->ts_s;
    cc.mpcc.rho = c->rho;
    cc.mpcc.dead_time_s = c->dead_time_s;
    cc.mpcc.v_drop_v = c->v_drop_v;
    cc.mpcc.i_dt_a = c->i_dt_a;
    cc.mpcc.cand_set =
        c->mpcc_candidates == PROTO_MPCC_CANDIDATES_ADJACENT ? MPCC_CAND_ADJACENT : MPCC_CAND_ALL8;
    foc_cfg_default(&cc.foc);
    cc.foc.ts_s = c->ts_s;
    cc.foc.bw_rad_s = c->foc_bw_rad_s;
    cc.foc.dead_time_s = c->dead_time_s;
    cc.foc.v_drop_v = c->v_drop_v;
    cc.foc.i_dt_a = c->i_dt_a;
    cc_init(&f->cc, &cc);
    f->cc_cfg = cc;
    f->cc_want = f->cc.kind;
    f->u_d_mean_v = 0.0f;
    f->u_q_mean_v = 0.0f;
    memset(&f->cc_out, 0, sizeof(f->cc_out));

    ic.nominal.r_s_ohm = f->motor.r_s_ohm;
    ic.nominal.l_d_h = f->motor.l_d_h;
    ic.nominal.l_q_h = f->motor.l_q_h;
    ic.nominal.psi_f_wb = f->motor.psi_f_wb;
    ic.pred_scale.r_s_ohm = c->pred_scale_r_s;
    ic.pred_scale.l_d_h = c->pred_scale_l_d;
    ic.pred_scale.l_q_h = c->pred_scale_l_q;
    ic.pred_scale.psi_f_wb = c->pred_scale_psi_f;
    ic.pole_pairs = f->motor.pole_pairs;
    ic.ts_s = c->ts_s;
    ic.id_window = c->id_window;
    ic.identify = c->identify != 0u;
    ic.predictor = c->predictor;
    ic.have_injection = false;
    for (i = 0u; i < f->prof.n_declared && i < PROFILE_MAX_SEGMENTS; i++) {
        if (f->prof.seg[i].kind == PROFILE_KIND_IDENTIFY_R) {
            ic.have_injection = true;
        }
    }
    /* the encoder count is the floor of the angle: half a count (electrical) of mean lag */
    ic.angle_bias_rad =
        c->enc_counts > 0u ? FW_PI_F * (float)f->motor.pole_pairs / (float)c->enc_counts : 0.0f;
    ident_init(&f->ident, &ic);
    memset(&f->seg, 0, sizeof(f->seg));
}

uint16_t fw_start_run(fw_t *f)
{
    ramp_cfg_t sr;
    if (!f->have_motor || !f->have_ctrl || !profile_complete(&f->prof)) {
        return PROTO_ACK_STATUS_BAD_STATE;
    }
    if (fw_active(f)) {
        return PROTO_ACK_STATUS_BUSY;
    }
    init_stages(f);
    capture_init(&f->cap, f->ctrl.capture_pre);
    profile_start(&f->prof, f->ctrl.ts_s);
    memset(&f->sig, 0, sizeof(f->sig));
    f->i_s_ref_a = 0.0f;
    f->i_d_base_a = 0.0f;
    f->speed_div_count = 0u;
    f->faults = 0u;
    f->commissioning = false;
    f->tick = 0u;
    fw_tel_start(f);
    f->hb_isr = f->isr_count;
    f->hb_lost = false;
    f->state = PROTO_STATE_RUNNING;
    f->stop_reason = 0u;
    sr.rate_rpm_s = FW_STOP_RAMP_RPM_S;
    sr.ts_s = f->ctrl.ts_s;
    ramp_init(&f->stop.ramp, &sr);
    return PROTO_ACK_STATUS_OK;
}
