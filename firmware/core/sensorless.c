/* The sensorless angle source: ripple PLL, polarity test, hybrid, supervision (sensorless.h). */
#include "sensorless.h"

#include <string.h>

void snl_init(snl_t *s, const snl_cfg_t *cfg)
{
    float n;
    memset(s, 0, sizeof(*s));
    s->cfg = *cfg;
    rpll_init(&s->pll, &cfg->pll);
    pol_init(&s->pol, &cfg->pol);
    hyb_init(&s->hyb, &cfg->hyb);
    n = cfg->hyb.lost_s / cfg->pll.ts_s;
    s->n_low_max = n >= 1.0f && n < 1.0e8f ? (uint32_t)n : 1u;
}

static void lose(snl_t *s, uint16_t why, snl_out_t *out)
{
    if (s->lock == SNL_LOCK_OK) {
        s->lock = why;
        out->lock_lost_now = true;
    }
}

void snl_step(snl_t *s, const snl_in_t *in, snl_out_t *out)
{
    rpll_in_t pi;
    rpll_out_t po;
    pol_in_t qi;
    pol_out_t qo;
    memset(out, 0, sizeof(*out));
    pi.i_alpha_a = in->i_alpha_a;
    pi.i_beta_a = in->i_beta_a;
    pi.u_alpha_v = in->u_alpha_prev_v;
    pi.u_beta_v = in->u_beta_prev_v;
    pi.u_valid = in->u_valid;
    rpll_step(&s->pll, &pi, &po);

    qi.di_d_a = po.di_d_a;
    qi.u_d_v = po.u_d_v;
    qi.i_d_a = po.i_d_mid_a;
    qi.conf = po.conf;
    qi.excited = po.excited;
    pol_step(&s->pol, &qi, &qo);
    if (qo.flip_now) {
        rpll_flip(&s->pll);
        po.theta_e_rad = s->pll.th;
    }
    out->startup = qo.active;
    /* the polarity test's pulses alone while it runs; then the excitation (hybrid: the PLL's
     * share of it, below) */
    out->i_d_inject_a = (qo.active ? qo.i_d_ref_a : po.i_d_hf_a) + po.i_d_excite_a;
    out->pol_result = qo.result;
    out->pol_asym = qo.asym;
    out->pol_done_now = !qo.active && s->pol.result != POL_RUNNING && s->pol.tick != UINT32_MAX;
    if (out->pol_done_now) {
        s->pol.tick = UINT32_MAX; /* reported once */
        if (qo.result == POL_UNRESOLVED) {
            lose(s, SNL_LOCK_POLARITY, out);
        } else if (qo.result == POL_NO_LOCK) {
            lose(s, SNL_LOCK_NO_START, out);
        }
    }

    out->theta_pll_rad = po.theta_e_rad;
    out->conf = po.conf;
    out->err_rad = po.err_rad;
    out->theta_e_rad = po.theta_e_rad;
    out->omega_e_rad_s = po.omega_e_rad_s;
    if (s->cfg.mode == SNL_MODE_HYBRID && !qo.active) {
        hyb_in_t hi;
        hyb_out_t ho;
        hi.theta_pll_rad = po.theta_e_rad;
        hi.omega_pll_rad_s = po.omega_e_rad_s;
        hi.conf_pll = po.conf;
        hi.theta_mras_rad = in->theta_mras_rad;
        hi.omega_mras_rad_s = in->omega_mras_rad_s;
        hi.mras_locked = in->mras_locked;
        hyb_step(&s->hyb, &hi, &ho);
        out->theta_e_rad = ho.theta_e_rad;
        out->omega_e_rad_s = ho.omega_e_rad_s;
        out->w_mras = ho.w_mras;
        out->i_d_inject_a -= ho.w_mras * po.i_d_hf_a;
        if (ho.lock == HYB_LOCK_DISAGREE) {
            lose(s, SNL_LOCK_DISAGREE, out);
        } else if (ho.lock == HYB_LOCK_LOW_CONF) {
            lose(s, SNL_LOCK_LOW_CONF, out);
        }
    } else if (!qo.active) {
        s->n_low = po.conf >= s->cfg.hyb.conf_min ? 0u : s->n_low + 1u;
        if (s->n_low >= s->n_low_max) {
            lose(s, SNL_LOCK_LOW_CONF, out);
        }
    }
    out->lock = s->lock;
    /* no torque on an angle that cannot be trusted: the references stay held (zero current) from
     * a loss of lock until the caller's fault switches the PWM off */
    out->startup = out->startup || s->lock != SNL_LOCK_OK;
    out->valid =
        !qo.active && s->lock == SNL_LOCK_OK && (qo.result == POL_KEPT || qo.result == POL_FLIPPED);
}
