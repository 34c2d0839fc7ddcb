/* Ripple/saliency PLL (est_ripple_pll.h; derivation in docs/sensorless.md). */
#include "est_ripple_pll.h"

#include <math.h>
#include <string.h>

#include "transforms.h"

void rpll_init(rpll_t *e, const rpll_cfg_t *cfg)
{
    float bw, dmin;
    rerr_g_t g0;
    memset(e, 0, sizeof(*e));
    e->cfg = *cfg;
    if (!(e->cfg.bw_rad_s > 0.0f)) {
        e->cfg.bw_rad_s = RPLL_BW_DEFAULT_RAD_S;
    }
    if (!(e->cfg.norm_tau_s > 0.0f)) {
        e->cfg.norm_tau_s = RPLL_NORM_TAU_DEFAULT_S;
    }
    if (!(e->cfg.conf_tau_s > 0.0f)) {
        e->cfg.conf_tau_s = RPLL_CONF_TAU_DEFAULT_S;
    }
    if (!(e->cfg.j_kgm2 > 0.0f)) {
        e->cfg.torque_ff = false;
    }
    bw = e->cfg.bw_rad_s;
    if (bw * e->cfg.ts_s > 0.05f) { /* far inside the discrete observer's stability region */
        bw = 0.05f / e->cfg.ts_s;
    }
    e->l1 = 3.0f * bw;
    e->l2 = 3.0f * bw * bw;
    e->l3 = bw * bw * bw;
    e->tau_w_s = RPLL_SPEED_TAU_BW / bw;
    e->k_wf = e->cfg.ts_s / (e->tau_w_s + e->cfg.ts_s);
    e->k_norm = e->cfg.ts_s / (e->cfg.norm_tau_s + e->cfg.ts_s);
    e->k_conf = e->cfg.ts_s / (e->cfg.conf_tau_s + e->cfg.ts_s);
    e->k_hp = e->cfg.ts_s / (RPLL_HP_TAU_S + e->cfg.ts_s);
    /* floor of the normaliser: an applied 5 V across the inductances (a tenth of a percent of an
     * active vector's |U|^2 at 540 V) */
    rerr_gamma_at(&e->cfg.gamma, 0.0f, 0.0f, &g0);
    dmin = 0.5f * (g0.g_dd - g0.g_qq);
    e->norm_floor = e->cfg.ts_s * dmin * dmin * 25.0f;
    /* excitation wanted below the normaliser of one active vector (2/3 v_dc, 540 V) in 50 periods */
    e->norm_excite = e->cfg.ts_s * dmin * dmin * 360.0f * 360.0f * 0.02f;
    rpll_reset(e, 0.0f, 0.0f);
}

void rpll_reset(rpll_t *e, float theta_e_rad, float omega_e_rad_s)
{
    e->th = tf_wrap_2pi(theta_e_rad);
    e->w = omega_e_rad_s;
    e->w_f = omega_e_rad_s;
    e->acc = 0.0f;
    e->norm_f = 0.0f;
    e->conf_f = 0.0f;
    e->m_ed = 0.0f;
    e->m_eq = 0.0f;
    e->m_ud = 0.0f;
    e->m_uq = 0.0f;
    e->u_prev_d = 0.0f;
    e->u_prev_q = 0.0f;
    e->r2_f = 0.0f;
    e->exc_tick = 0u;
    e->hf_sign = 1.0f;
    e->have_prev = false;
}

void rpll_flip(rpll_t *e)
{
    e->th = tf_wrap_2pi(e->th + FW_PI_F);
    e->conf_f = 0.0f;
}

void rpll_pull(rpll_t *e, float theta_e_rad, float omega_e_rad_s, float frac)
{
    e->th = tf_wrap_2pi(e->th + frac * tf_wrap_pi(theta_e_rad - e->th));
    e->w += frac * (omega_e_rad_s - e->w);
    e->w_f += frac * (omega_e_rad_s - e->w_f);
}

void rpll_step(rpll_t *e, const rpll_in_t *in, rpll_out_t *out)
{
    const rpll_cfg_t *c = &e->cfg;
    const float ts = c->ts_s, w = e->w;
    float d = 0.0f, a_ff = 0.0f;
    memset(out, 0, sizeof(*out));
    if (e->have_prev && in->u_valid) {
        const float thm = e->th + 0.5f * w * ts; /* middle of [k-1, k): th is the angle at k-1 */
        const float cm = cosf(thm), sm = sinf(thm);
        float im_d, im_q, di_d, di_q, u_d, u_q, ud, uq, psi_d, psi_q;
        rerr_in_t ri;
        rerr_out_t ro;
        tf_park(0.5f * (in->i_alpha_a + e->i_al_prev), 0.5f * (in->i_beta_a + e->i_be_prev), cm, sm,
                &im_d, &im_q);
        tf_park(in->i_alpha_a - e->i_al_prev, in->i_beta_a - e->i_be_prev, cm, sm, &di_d, &di_q);
        tf_park(in->u_alpha_v, in->u_beta_v, cm, sm, &u_d, &u_q);
        psi_d = c->psi_f_wb + c->l_d_h * im_d;
        psi_q = c->l_q_h * im_q;
        ud = u_d - c->r_s_ohm * im_d + w * psi_q;
        uq = u_q - c->r_s_ohm * im_q - w * psi_d;
        /* rotation of the frame over the period: the alpha-beta change holds w Ts J i_m */
        di_d += w * ts * im_q;
        di_q -= w * ts * im_d;
        rerr_gamma_at(&c->gamma, im_d, im_q, &ri.g);
        if (c->gamma.tab != NULL) { /* Simpson over the step: Gamma varies along a 3 A ripple */
            rerr_g_t g0, g1;
            float i0d, i0q;
            tf_park(e->i_al_prev, e->i_be_prev, cm, sm, &i0d, &i0q);
            rerr_gamma_at(&c->gamma, i0d, i0q, &g0);
            rerr_gamma_at(&c->gamma, 2.0f * im_d - i0d, 2.0f * im_q - i0q, &g1);
            ri.g.g_dd = (g0.g_dd + 4.0f * ri.g.g_dd + g1.g_dd) * (1.0f / 6.0f);
            ri.g.g_qq = (g0.g_qq + 4.0f * ri.g.g_qq + g1.g_qq) * (1.0f / 6.0f);
            ri.g.g_dq = (g0.g_dq + 4.0f * ri.g.g_dq + g1.g_dq) * (1.0f / 6.0f);
            ri.g.g_qd = (g0.g_qd + 4.0f * ri.g.g_qd + g1.g_qd) * (1.0f / 6.0f);
        }
        ri.e_d_a = di_d - ts * (ri.g.g_dd * ud + ri.g.g_dq * uq);
        ri.e_q_a = di_q - ts * (ri.g.g_qd * ud + ri.g.g_qq * uq);
        {
            /* current-sample delay tau: the sampled step holds tau of the previous period's
             * slope instead of this one's, di_s = di - tau Gamma (U - U_prev); tau by NLMS */
            const float dud = ud - e->u_prev_d, duq = uq - e->u_prev_q;
            const float r_d = -(ri.g.g_dd * dud + ri.g.g_dq * duq);
            const float r_q = -(ri.g.g_qd * dud + ri.g.g_qq * duq);
            const float r2 = r_d * r_d + r_q * r_q;
            ri.e_d_a -= e->tau_s * r_d;
            ri.e_q_a -= e->tau_s * r_q;
            e->r2_f += e->k_norm * (r2 - e->r2_f);
            if (e->r2_f > 0.0f && e->conf_f > 0.8f) {
                e->tau_s += RPLL_TAU_GAIN * (ri.e_d_a * r_d + ri.e_q_a * r_q) / e->r2_f;
                e->tau_s = e->tau_s < 0.0f ? 0.0f : (e->tau_s > 0.5f * ts ? 0.5f * ts : e->tau_s);
            }
            e->u_prev_d = ud;
            e->u_prev_q = uq;
        }
        /* the ripple only: the slow parts of e and U (back-EMF and flux errors of a wrong angle,
         * correlated with each other, not with the switching) are removed by running means */
        e->m_ed += e->k_hp * (ri.e_d_a - e->m_ed);
        e->m_eq += e->k_hp * (ri.e_q_a - e->m_eq);
        e->m_ud += e->k_hp * (ud - e->m_ud);
        e->m_uq += e->k_hp * (uq - e->m_uq);
        ri.e_d_a -= e->m_ed;
        ri.e_q_a -= e->m_eq;
        ri.u_d_v = ud - e->m_ud;
        ri.u_q_v = uq - e->m_uq;
        rerr_eval(&ri, ts, &ro);
        e->norm_f += e->k_norm * (ro.norm - e->norm_f);
        out->excited = e->norm_f > e->norm_floor;
        if (out->excited) {
            d = 0.5f * ro.sn / e->norm_f;
            if (d > 0.5f) {
                d = 0.5f;
            } else if (d < -0.5f) {
                d = -0.5f;
            }
            e->conf_f += e->k_conf * (1.0f + ro.cn / e->norm_f - e->conf_f);
        }
        out->di_d_a = di_d;
        out->u_d_v = ud;
        out->i_d_mid_a = im_d;
        out->torque_nm = 1.5f * (float)c->pole_pairs *
                         (c->psi_f_wb * im_q + (c->l_d_h - c->l_q_h) * im_d * im_q);
        if (c->torque_ff) {
            a_ff = (float)c->pole_pairs * out->torque_nm / c->j_kgm2;
        }
    }
    e->i_al_prev = in->i_alpha_a;
    e->i_be_prev = in->i_beta_a;
    e->have_prev = true;
    e->th = tf_wrap_2pi(e->th + ts * (w + e->l1 * d));
    e->w = w + ts * (a_ff + e->acc + e->l2 * d);
    /* the speed output: low-passed, with the observer's own acceleration times tau added, so
     * that a ramp (known torque) or a settled load leaves no lag */
    e->w_f += e->k_wf * (e->w + e->tau_w_s * (a_ff + e->acc) - e->w_f);
    e->acc += ts * e->l3 * d;
    if (c->excite_a > 0.0f) {
        out->i_d_hf_a = e->hf_sign * c->excite_a;
        e->hf_sign = -e->hf_sign;
    }
    /* too little ripple to see the saliency: a d-axis square wave (no torque at i_q = 0) */
    if (e->norm_f < e->norm_excite) {
        e->exc_tick = (uint16_t)((e->exc_tick + 1u) % (2u * RPLL_EXCITE_HALF_PERIODS));
        out->i_d_excite_a = e->exc_tick < RPLL_EXCITE_HALF_PERIODS ? RPLL_EXCITE_A : -RPLL_EXCITE_A;
    }
    out->theta_e_rad = e->th;
    out->omega_e_rad_s = e->w_f;
    out->err_rad = d;
    out->conf = e->conf_f;
}
