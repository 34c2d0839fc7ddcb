/* FOC current loops with SVPWM (foc.h, docs/sensorless.md). C28x-safe. */
#include "foc.h"
#include "fw_types.h"
#include "transforms.h"

#include <math.h>

#define FOC_L_MIN_H 1.0e-7f

void foc_cfg_default(foc_cfg_t *cfg)
{
    cfg->ts_s = 100.0e-6f;
    cfg->bw_rad_s = 0.0f;
    cfg->dead_time_s = 0.0f;
    cfg->v_drop_v = 0.0f;
    cfg->i_dt_a = 0.0f;
}

void foc_init(foc_t *c, const foc_cfg_t *cfg)
{
    c->cfg = *cfg;
    if (!(c->cfg.ts_s > 0.0f)) {
        c->cfg.ts_s = 100.0e-6f;
    }
    if (!(c->cfg.bw_rad_s > 0.0f) || !(c->cfg.bw_rad_s * c->cfg.ts_s < 0.5f)) {
        c->cfg.bw_rad_s = FW_TWO_PI_F / (20.0f * c->cfg.ts_s);
    }
    if (!(c->cfg.dead_time_s >= 0.0f)) {
        c->cfg.dead_time_s = 0.0f;
    }
    if (!(c->cfg.v_drop_v >= 0.0f)) {
        c->cfg.v_drop_v = 0.0f;
    }
    foc_reset(c);
}

void foc_reset(foc_t *c)
{
    c->x_d_v = 0.0f;
    c->x_q_v = 0.0f;
    c->u_al_app = 0.0f;
    c->u_be_app = 0.0f;
    c->u_al_next = 0.0f;
    c->u_be_next = 0.0f;
}

void foc_take_over(foc_t *c, float u_alpha_v, float u_beta_v, float x_d_v, float x_q_v)
{
    foc_reset(c);
    if (u_alpha_v == u_alpha_v && u_beta_v == u_beta_v) {
        c->u_al_next = u_alpha_v;
        c->u_be_next = u_beta_v;
    }
    if (x_d_v == x_d_v && x_q_v == x_q_v) {
        c->x_d_v = x_d_v;
        c->x_q_v = x_q_v;
    }
}

void foc_gains(const foc_cfg_t *cfg, float r_ohm, float l_h, float *kp, float *ki)
{
    *kp = cfg->bw_rad_s * l_h;
    *ki = cfg->bw_rad_s * r_ohm;
}

static float smooth_sign(float i, float i_dt)
{
    float x, x2;
    if (!(i_dt > 0.0f)) {
        return i > 0.0f ? 1.0f : (i < 0.0f ? -1.0f : 0.0f);
    }
    x = i / i_dt;
    if (x >= 3.0f) {
        return 1.0f;
    }
    if (x <= -3.0f) {
        return -1.0f;
    }
    x2 = x * x;
    return x * (27.0f + x2) / (27.0f + 9.0f * x2);
}

static float clampf(float x, float lo, float hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

static float clamp01(float x)
{
    return x < 0.0f ? 0.0f : (x > 1.0f ? 1.0f : x);
}

/* One PI axis with back-calculation: the integrator holds what the limited output needs. */
static float pi_axis(float *x, float kp, float ki_ts, float e, float ff)
{
    *x += ki_ts * e;
    return kp * e + *x + ff;
}

void foc_step(foc_t *c, const foc_in_t *in, foc_out_t *out)
{
    const float ts = c->cfg.ts_s;
    const float w = in->omega_e_rad_s;
    const float l_d = in->l_d_h > FOC_L_MIN_H ? in->l_d_h : FOC_L_MIN_H;
    const float l_q = in->l_q_h > FOC_L_MIN_H ? in->l_q_h : FOC_L_MIN_H;
    const float r = in->r_s_ohm;
    const float c0 = in->cos_theta, s0 = in->sin_theta;
    float kp_d, ki_d, kp_q, ki_q, u_d, u_q, u_d1, u_q1, i_d1, i_q1, e_d, e_q, ff_d, ff_q, u_max;
    float ph, cph, sph, u_al, u_be, va, vb, vc, vmax, vmin, off, inv_vdc, k_dt;
    float i_al, i_be, ia, ib, ic;

    /* the voltage applied during [k, k+1): decided last call */
    c->u_al_app = c->u_al_next;
    c->u_be_app = c->u_be_next;
    tf_park(c->u_al_app, c->u_be_app, c0, s0, &out->u_d_v, &out->u_q_v);
    ph = 0.5f * w * ts;
    cph = c0 * cosf(ph) - s0 * sinf(ph);
    sph = s0 * cosf(ph) + c0 * sinf(ph);
    tf_park(c->u_al_app, c->u_be_app, cph, sph, &u_d1, &u_q1);
    out->u_d_avg_v = u_d1;
    out->u_q_avg_v = u_q1;
    out->u_alpha_v = c->u_al_app;
    out->u_beta_v = c->u_be_app;

    /* 1. i(k+1) (delay compensation), in the frame at k+1 */
    i_d1 = in->i_d_a + ts / l_d * (u_d1 - r * in->i_d_a + w * l_q * in->i_q_a);
    i_q1 = in->i_q_a + ts / l_q * (u_q1 - r * in->i_q_a - w * l_d * in->i_d_a - w * in->psi_f_wb);
    out->i_d_k1_a = i_d1;
    out->i_q_k1_a = i_q1;

    /* 2. PI with decoupling */
    foc_gains(&c->cfg, r, l_d, &kp_d, &ki_d);
    foc_gains(&c->cfg, r, l_q, &kp_q, &ki_q);
    e_d = in->i_d_ref_a - i_d1;
    e_q = in->i_q_ref_a - i_q1;
    ff_d = -w * l_q * i_q1;
    ff_q = w * (l_d * i_d1 + in->psi_f_wb);
    if (!(e_d == e_d) || !(e_q == e_q) || !(ff_d == ff_d) || !(ff_q == ff_q)) {
        e_d = e_q = ff_d = ff_q = 0.0f; /* non-finite input: zero voltage */
    }
    u_d = pi_axis(&c->x_d_v, kp_d, ki_d * ts, e_d, ff_d);
    u_q = pi_axis(&c->x_q_v, kp_q, ki_q * ts, e_q, ff_q);

    /* 3. voltage limit (linear SVPWM range), d first; back-calculation of the integrators */
    u_max = in->v_dc_v > 0.0f ? in->v_dc_v * TF_INV_SQRT3_F : 0.0f;
    out->limited = false;
    {
        float ud_l = u_d > u_max ? u_max : (u_d < -u_max ? -u_max : u_d);
        float q_room = sqrtf(u_max * u_max - ud_l * ud_l);
        float uq_l = u_q > q_room ? q_room : (u_q < -q_room ? -q_room : u_q);
        if (ud_l != u_d || uq_l != u_q) {
            /* conditional integration: this period's integration is taken back, and each
             * integrator is held where its output alone (with the feed-forward) stays within
             * the range */
            out->limited = true;
            c->x_d_v -= ki_d * ts * e_d;
            c->x_q_v -= ki_q * ts * e_q;
            c->x_d_v = clampf(c->x_d_v, -u_max - ff_d, u_max - ff_d);
            c->x_q_v = clampf(c->x_q_v, -u_max - ff_q, u_max - ff_q);
        }
        u_d = ud_l;
        u_q = uq_l;
    }
    out->u_d_cmd_v = u_d;
    out->u_q_cmd_v = u_q;

    /* 4. to the stationary frame at the middle of [k+1, k+2), SVPWM, dead-time compensation */
    ph = 1.5f * w * ts;
    cph = c0 * cosf(ph) - s0 * sinf(ph);
    sph = s0 * cosf(ph) + c0 * sinf(ph);
    tf_inv_park(u_d, u_q, cph, sph, &u_al, &u_be);
    c->u_al_next = u_al;
    c->u_be_next = u_be;
    tf_inv_clarke(u_al, u_be, &va, &vb, &vc);
    vmax = va > vb ? (va > vc ? va : vc) : (vb > vc ? vb : vc);
    vmin = va < vb ? (va < vc ? va : vc) : (vb < vc ? vb : vc);
    off = -0.5f * (vmax + vmin);
    inv_vdc = in->v_dc_v > 1.0f ? 1.0f / in->v_dc_v : 0.0f;
    k_dt = c->cfg.dead_time_s / ts + c->cfg.v_drop_v * inv_vdc;
    /* the phase currents expected over [k+1, k+2): i(k+1) at the angle of its middle */
    tf_inv_park(i_d1, i_q1, cph, sph, &i_al, &i_be);
    tf_inv_clarke(i_al, i_be, &ia, &ib, &ic);
    out->duty_a = clamp01(0.5f + (va + off) * inv_vdc + k_dt * smooth_sign(ia, c->cfg.i_dt_a));
    out->duty_b = clamp01(0.5f + (vb + off) * inv_vdc + k_dt * smooth_sign(ib, c->cfg.i_dt_a));
    out->duty_c = clamp01(0.5f + (vc + off) * inv_vdc + k_dt * smooth_sign(ic, c->cfg.i_dt_a));
}
