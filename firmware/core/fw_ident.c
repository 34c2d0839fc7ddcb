/* Online identification inside the control period: R injection, window averages, the three
 * estimators, and what feeds the MPCC predictor (docs/identification.md). */
#include "fw_internal.h"
#include "transforms.h"

#include <math.h>
#include <string.h>

/* ------------------------------------------------------------------ identification */

void fw_ident_init(fw_t *f)
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
float fw_est_r_report(const fw_t *f, uint16_t k)
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
void fw_predictor_params(fw_t *f, mpcc_in_t *mi)
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
float fw_d_current_ref(const fw_t *f)
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
void fw_ident_step(fw_t *f, const fw_meas_t *m, const mpcc_out_t *mo)
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
            fw_send_event(f, PROTO_EVENT_R_IDENTIFIED, (int32_t)(f->r_ident_ohm * 1000.0f + 0.5f));
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

