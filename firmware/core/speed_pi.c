/* Speed PI with conditional-integration anti-windup. See speed_pi.h and docs/control.md. */
#include "speed_pi.h"

#include <math.h>

void speed_pi_init(speed_pi_t *p, const speed_pi_cfg_t *cfg)
{
    p->cfg = *cfg;
    if (!(p->cfg.out_max_a >= 0.0f)) {
        p->cfg.out_max_a = 0.0f;
    }
    if (!(p->cfg.ts_s > 0.0f)) {
        p->cfg.ts_s = 1.0e-3f;
    }
    p->ref_weight = 1.0f;
    speed_pi_reset(p, 0.0f);
}

void speed_pi_set_ref_weight(speed_pi_t *p, float b)
{
    p->ref_weight = (b > 1.0f) ? 1.0f : ((b > 0.0f) ? b : 0.0f);
}

static float clampf(float x, float lim)
{
    if (x > lim) {
        return lim;
    }
    if (x < -lim) {
        return -lim;
    }
    return x;
}

void speed_pi_reset(speed_pi_t *p, float out0_a)
{
    p->integ_a = clampf(out0_a, p->cfg.out_max_a);
    p->out_a = p->integ_a;
    p->saturated = false;
}

void speed_pi_preset(speed_pi_t *p, float out0_a, float ref_rad_s, float meas_rad_s)
{
    const float prop = p->cfg.kp_a_per_rad_s * (p->ref_weight * ref_rad_s - meas_rad_s);
    const float i_lim =
        p->cfg.out_max_a + fabsf(p->cfg.kp_a_per_rad_s * (1.0f - p->ref_weight) * ref_rad_s);
    p->integ_a = clampf(clampf(out0_a, p->cfg.out_max_a) - prop, i_lim);
    p->out_a = clampf(out0_a, p->cfg.out_max_a);
    p->saturated = false;
}

void speed_pi_set_limit(speed_pi_t *p, float out_max_a)
{
    p->cfg.out_max_a = (out_max_a >= 0.0f) ? out_max_a : 0.0f;
    p->integ_a = clampf(p->integ_a, p->cfg.out_max_a);
}

float speed_pi_step(speed_pi_t *p, float ref_rad_s, float meas_rad_s)
{
    const float lim = p->cfg.out_max_a;
    const float e = ref_rad_s - meas_rad_s;
    const float prop = p->cfg.kp_a_per_rad_s * (p->ref_weight * ref_rad_s - meas_rad_s);
    /* integrator bound: the clamp, widened by what the set-point weight takes off the P term
     * (with b < 1 the integrator carries kp (1 - b) ref in steady state) */
    const float i_lim = lim + fabsf(p->cfg.kp_a_per_rad_s * (1.0f - p->ref_weight) * ref_rad_s);
    const float integ_new = clampf(p->integ_a + p->cfg.ki_a_per_rad * p->cfg.ts_s * e, i_lim);
    float u = prop + integ_new;

    if (!(u == u)) { /* NaN input: hold the last output, keep the state */
        return p->out_a;
    }
    /* conditional integration: accept the new integrator value unless the output saturates and
     * the error drives it deeper into saturation */
    if ((u > lim && e > 0.0f) || (u < -lim && e < 0.0f)) {
        u = prop + p->integ_a;
    } else {
        p->integ_a = integ_new;
    }
    p->saturated = (u > lim) || (u < -lim);
    u = clampf(u, lim);
    p->out_a = u;
    return u;
}

void speed_pi_design(float j_kgm2, float kt_nm_per_a, float bw_rad_s, float *kp, float *ki)
{
    if (!(kt_nm_per_a > 0.0f) || !(j_kgm2 > 0.0f) || !(bw_rad_s > 0.0f)) {
        *kp = 0.0f;
        *ki = 0.0f;
        return;
    }
    *kp = j_kgm2 * bw_rad_s / kt_nm_per_a;
    *ki = *kp * bw_rad_s * 0.25f;
}
