/* Online identification (ident.h, docs/identification.md). */
#include "ident.h"

#include <math.h>
#include <string.h>

/* ------------------------------------------------------------------ operations table */

static void rls_init(void *e, const est_cfg_t *c)
{
    est_rls_init((est_rls_t *)e, c);
}
static void rls_set_r(void *e, float r)
{
    est_rls_set_r((est_rls_t *)e, r);
}
static void rls_step(void *e, const id_sample_t *s, est_out_t *o)
{
    est_rls_step((est_rls_t *)e, s, o);
}
static void ada_init(void *e, const est_cfg_t *c)
{
    est_adaline_init((est_adaline_t *)e, c);
}
static void ada_set_r(void *e, float r)
{
    est_adaline_set_r((est_adaline_t *)e, r);
}
static void ada_step(void *e, const id_sample_t *s, est_out_t *o)
{
    est_adaline_step((est_adaline_t *)e, s, o);
}
static void nlms_init(void *e, const est_cfg_t *c)
{
    est_nlms_init((est_nlms_t *)e, c);
}
static void nlms_set_r(void *e, float r)
{
    est_nlms_set_r((est_nlms_t *)e, r);
}
static void nlms_step(void *e, const id_sample_t *s, est_out_t *o)
{
    est_nlms_step((est_nlms_t *)e, s, o);
}

static const est_ops_t k_ops_rls = { rls_init, rls_set_r, rls_step };
static const est_ops_t k_ops_adaline = { ada_init, ada_set_r, ada_step };
static const est_ops_t k_ops_nlms = { nlms_init, nlms_set_r, nlms_step };

/* ------------------------------------------------------------------ object */

void ident_init(ident_t *id, const ident_cfg_t *cfg)
{
    est_cfg_t ec;
    idw_cfg_t wc;
    rinj_cfg_t rc;
    uint16_t k;
    memset(id, 0, sizeof(*id));
    id->cfg = *cfg;
    id->ops[IDENT_EST_RLS] = &k_ops_rls;
    id->est[IDENT_EST_RLS] = &id->rls;
    id->ops[IDENT_EST_ADALINE] = &k_ops_adaline;
    id->est[IDENT_EST_ADALINE] = &id->ada;
    id->ops[IDENT_EST_NLMS] = &k_ops_nlms;
    id->est[IDENT_EST_NLMS] = &id->nlms;
    est_cfg_default(&ec, cfg->nominal.r_s_ohm, cfg->nominal.l_d_h, cfg->nominal.l_q_h,
                    cfg->nominal.psi_f_wb, cfg->pole_pairs);
    for (k = 0u; k < IDENT_N_EST; k++) {
        id->ops[k]->init(id->est[k], &ec);
    }
    wc.n_periods = cfg->id_window;
    wc.ts_s = cfg->ts_s;
    wc.sector_sync = true;
    idw_init(&id->idw, &wc);
    rc.sep_min = 0.02f;
    rc.n_window = cfg->id_window >= 2u ? cfg->id_window : 20u;
    rc.ts_s = cfg->ts_s;
    rc.l_d_h = cfg->nominal.l_d_h;
    rc.l_q_h = cfg->nominal.l_q_h;
    rinj_init(&id->rinj, &rc);
    id->idw_step_seen = true;
}

void ident_report(const ident_t *id, uint16_t k, est_out_t *out)
{
    *out = id->out[k];
    if (id->r_injecting && !id->r_identified) {
        out->r_s_ohm = id->rinj_out.r_s_ohm;
    } else if (id->cfg.have_injection && !id->r_identified) {
        out->r_s_ohm = 0.0f;
    }
}

bool ident_nominal_feeds(const ident_t *id)
{
    return !id->cfg.identify || id->cfg.predictor == 0u || !id->pred_latched;
}

/* The chosen estimator once it has converged (R from the injection until then), else the motor
 * file's values times the profile's mismatch factors. */
void ident_predictor(ident_t *id, cc_params_t *out)
{
    const ident_cfg_t *c = &id->cfg;
    out->r_s_ohm = c->nominal.r_s_ohm * c->pred_scale.r_s_ohm;
    out->l_d_h = c->nominal.l_d_h * c->pred_scale.l_d_h;
    out->l_q_h = c->nominal.l_q_h * c->pred_scale.l_q_h;
    out->psi_f_wb = c->nominal.psi_f_wb * c->pred_scale.psi_f_wb;
    if (c->identify && c->predictor != 0u && c->predictor <= IDENT_N_EST) {
        const est_out_t *o = &id->out[c->predictor - 1u];
        if (id->r_identified) {
            out->r_s_ohm = id->r_ident_ohm;
        }
        if (!id->pred_latched && o->converged) {
            id->pred_latched = true;
        }
        if (id->pred_latched && o->l_d_h > 0.0f && o->l_q_h > 0.0f) {
            out->r_s_ohm = o->r_s_ohm;
            out->l_d_h = o->l_d_h;
            out->l_q_h = o->l_q_h;
            out->psi_f_wb = o->psi_f_wb;
        }
    }
}

bool ident_converged_params(const ident_t *id, cc_params_t *out)
{
    const ident_cfg_t *c = &id->cfg;
    const est_out_t *o;
    if (!id->pred_latched || !c->identify || c->predictor == 0u || c->predictor > IDENT_N_EST) {
        return false;
    }
    o = &id->out[c->predictor - 1u];
    if (!(o->l_d_h > 0.0f && o->l_q_h > 0.0f && o->psi_f_wb > 0.0f)) {
        return false;
    }
    out->r_s_ohm = o->r_s_ohm;
    out->l_d_h = o->l_d_h;
    out->l_q_h = o->l_q_h;
    out->psi_f_wb = o->psi_f_wb;
    return true;
}

float ident_d_ref(const ident_t *id, const ident_seg_t *seg, float i_d_base_a)
{
    if (seg->identify_r) {
        return 2u * seg->tick < seg->ticks ? seg->inject_a : 0.5f * seg->inject_a;
    }
    if (seg->inject_a != 0.0f && seg->inject_hz > 0.0f) {
        const float ph = (float)seg->tick * id->cfg.ts_s * seg->inject_hz;
        const float frac = ph - floorf(ph);
        return i_d_base_a + (frac < 0.5f ? seg->inject_a : -seg->inject_a);
    }
    return i_d_base_a;
}

/* identify_r: the injection's windows, settling skipped; R at the segment's end. */
static void step_injection(ident_t *id, const ident_seg_t *seg, const ident_in_t *in,
                           ident_out_t *out)
{
    const uint32_t half = seg->ticks / 2u;
    const uint32_t t_in = seg->tick < half ? seg->tick : seg->tick - half;
    const uint32_t len = seg->tick < half ? half : seg->ticks - half;
    uint16_t k;
    id->r_injecting = true;
    if ((float)t_in >= IDENT_R_SETTLE_FRAC * (float)len) {
        rinj_in_t ri;
        ri.i_d_a = in->i_d_a;
        ri.i_q_a = in->i_q_a;
        ri.u_d_v = in->u_d_avg_v;
        ri.u_q_v = in->u_q_avg_v;
        ri.theta_e_rad = in->theta_e_rad;
        ri.i_a_a = in->i_a_a;
        ri.i_b_a = in->i_b_a;
        ri.i_c_a = in->i_c_a;
        rinj_step(&id->rinj, &ri, &id->rinj_out);
    } else {
        rinj_gap(&id->rinj); /* settling: the windows must not span the level change */
    }
    if (seg->tick + 1u >= seg->ticks && id->rinj_out.r_s_ohm > 0.0f) {
        id->r_ident_ohm = id->rinj_out.r_s_ohm;
        id->r_identified = true;
        id->r_injecting = false;
        for (k = 0u; k < IDENT_N_EST; k++) {
            id->ops[k]->set_r(id->est[k], id->r_ident_ohm);
        }
        for (k = 0u; k < IDENT_N_EST; k++) {
            id->out[k].r_s_ohm = id->r_ident_ohm;
        }
        out->r_identified_now = true;
        out->r_s_ohm = id->r_ident_ohm;
    }
    idw_reset(&id->idw);
}

void ident_step(ident_t *id, const ident_seg_t *seg, const ident_in_t *in, ident_out_t *out)
{
    out->r_identified_now = false;
    out->r_s_ohm = 0.0f;
    if (seg->identify_r) {
        step_injection(id, seg, in, out);
        return;
    }
    id->r_injecting = false;
    if (id->cfg.identify) {
        idw_in_t wi;
        id_sample_t smp;
        /* The encoder count is the floor of the angle: on average the true angle is half a count
         * ahead. The steady-state equations are sensitive to that bias (a rotation by delta moves
         * delta * u_q ~ 0.1 V into u_d at 1000 r/min, +0.4 % on L_q), so the estimators see u and i
         * in the frame of the mid-count angle: x(theta + delta) = rot(-delta) x(theta). */
        const float dl = id->cfg.angle_bias_rad;
        uint16_t k;
        wi.i_d_a = in->i_d_a + dl * in->i_q_a;
        wi.i_q_a = in->i_q_a - dl * in->i_d_a;
        wi.u_d_v = in->u_d_avg_v + dl * in->u_q_avg_v;
        wi.u_q_v = in->u_q_avg_v - dl * in->u_d_avg_v;
        wi.omega_e_rad_s = in->omega_e_rad_s;
        wi.theta_e_rad = in->theta_e_rad;
        if (idw_step(&id->idw, &wi, &smp)) {
            /* (6) is a steady-state equation: a window with a step of the i_d reference (the
             * excitation's edges) carries the current controller's transient and is skipped */
            if (!id->idw_step_seen && !seg->hold) {
                est_nlms_set_excitation(&id->nlms, seg->inject_hz > 0.0f ? seg->inject_a : 0.0f);
                for (k = 0u; k < IDENT_N_EST; k++) {
                    id->ops[k]->step(id->est[k], &smp, &id->out[k]);
                }
            }
            id->idw_step_seen = false;
        }
        if (fabsf(in->i_d_ref_a - id->id_ref_prev_a) > IDENT_STEP_A) {
            id->id_step_hold = IDENT_STEP_HOLD;
        }
        if (id->id_step_hold > 0u) {
            id->idw_step_seen = true; /* this period belongs to the running window */
            id->id_step_hold--;
        }
        id->id_ref_prev_a = in->i_d_ref_a;
    }
}
