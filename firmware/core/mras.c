/* MRAS speed and angle estimator (mras.h, docs/sensorless.md). C28x-safe. */
#include "mras.h"
#include "fw_types.h"
#include "transforms.h"

#include <math.h>

#define MRAS_BW_DEFAULT_RAD_S 300.0f
#define MRAS_FILT_RAD_S       100.0f /* residual filters for the lock decision */
#define MRAS_LOCK_EPS         0.25f  /* |filtered error signal| below this (rad) */
#define MRAS_LOCK_EMF_REL     0.3f   /* |measured EMF| within this fraction of |w_hat| psi_ex */
#define MRAS_L_MIN_H          1.0e-7f
#define MRAS_ACC_MAX          1.0e7f /* clamp of the load-acceleration state, rad/s^2 */

static float clampf(float x, float lo, float hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

void mras_init(mras_t *m, const mras_cfg_t *cfg)
{
    m->cfg = *cfg;
    if (!(m->cfg.bw_rad_s > 0.0f)) {
        m->cfg.bw_rad_s = MRAS_BW_DEFAULT_RAD_S;
    }
    if (!(m->cfg.min_speed_rad_s > 0.0f)) {
        m->cfg.min_speed_rad_s = 1.0f;
    }
    if (!(m->cfg.max_speed_rad_s > m->cfg.min_speed_rad_s)) {
        m->cfg.max_speed_rad_s = 100.0f * m->cfg.min_speed_rad_s;
    }
    if (!(m->cfg.l_d_h > MRAS_L_MIN_H)) {
        m->cfg.l_d_h = MRAS_L_MIN_H;
    }
    if (!(m->cfg.l_q_h > MRAS_L_MIN_H)) {
        m->cfg.l_q_h = MRAS_L_MIN_H;
    }
    m->l1 = 3.0f * m->cfg.bw_rad_s;
    m->l2 = 3.0f * m->cfg.bw_rad_s * m->cfg.bw_rad_s;
    m->l3 = m->cfg.bw_rad_s * m->cfg.bw_rad_s * m->cfg.bw_rad_s;
    m->acc_rad_s2 = 0.0f;
    m->theta_rad = tf_wrap_2pi(m->cfg.theta0_rad);
    /* a_ff = 1.5 p^2 / J (psi_ex i_q): electrical rad/s^2 per (Wb A); 0 without an inertia */
    m->ff_gain = (m->cfg.j_kgm2 > 0.0f && m->cfg.pole_pairs > 0u)
                     ? 1.5f * (float)m->cfg.pole_pairs * (float)m->cfg.pole_pairs / m->cfg.j_kgm2
                     : 0.0f;
    m->omega_i_rad_s = 0.0f;
    m->omega_rad_s = 0.0f;
    m->i_al_prev = 0.0f;
    m->i_be_prev = 0.0f;
    m->eps_f = 0.0f;
    m->e_w_f = 0.0f;
    m->emf_f = 0.0f;
    m->reverse = false;
    m->locked = false;
    m->n = 0u;
}

void mras_model_error(const mras_cfg_t *cfg, float i_al0, float i_be0, float i_al1, float i_be1,
                      float u_al, float u_be, float theta0_rad, float w_rad_s, float *e_d,
                      float *e_q)
{
    const float ts = cfg->ts_s;
    const float c0 = cosf(theta0_rad), s0 = sinf(theta0_rad);
    const float th_mid = theta0_rad + 0.5f * w_rad_s * ts;
    const float th1 = theta0_rad + w_rad_s * ts;
    float i_d0, i_q0, i_d1, i_q1, u_d, u_q, p_d, p_q;
    tf_park(i_al0, i_be0, c0, s0, &i_d0, &i_q0);
    tf_park(i_al1, i_be1, cosf(th1), sinf(th1), &i_d1, &i_q1);
    tf_park(u_al, u_be, cosf(th_mid), sinf(th_mid), &u_d, &u_q);
    /* Euler increment over the period in the frame of k-1 ... */
    p_d = ts / cfg->l_d_h * (u_d - cfg->r_s_ohm * i_d0 + w_rad_s * cfg->l_q_h * i_q0);
    p_q = ts / cfg->l_q_h *
          (u_q - cfg->r_s_ohm * i_q0 - w_rad_s * cfg->l_d_h * i_d0 - w_rad_s * cfg->psi_f_wb);
    /* ... seen in the frame of k: the cross coupling acts on the increment over half a period on
     * average (for L_d = L_q a rotation by -w Ts / 2; without it the angle error reads w Ts / 2
     * late), and the resistance on it (trapezoidal: 1 - R Ts / 2L) */
    {
        const float h = 0.5f * w_rad_s * ts;
        const float dd = (p_d + h * (cfg->l_q_h / cfg->l_d_h) * p_q) *
                         (1.0f - 0.5f * cfg->r_s_ohm * ts / cfg->l_d_h);
        const float dq = (p_q - h * (cfg->l_d_h / cfg->l_q_h) * p_d) *
                         (1.0f - 0.5f * cfg->r_s_ohm * ts / cfg->l_q_h);
        p_d = i_d0 + dd;
        p_q = i_q0 + dq;
    }
    *e_d = i_d1 - p_d;
    *e_q = i_q1 - p_q;
}

void mras_step(mras_t *m, const mras_in_t *in, mras_out_t *out)
{
    const mras_cfg_t *c = &m->cfg;
    const float ts = c->ts_s;
    const float w = m->omega_rad_s; /* the speed the frame turned at over [k-1, k) */
    const float theta_prev = m->theta_rad - w * ts; /* theta_hat(k-1) */
    const float w_min = c->min_speed_rad_s;
    const float a_f = MRAS_FILT_RAD_S * ts;
    float e_d = 0.0f, e_q = 0.0f, eps = 0.0f, ratio = 0.0f, a_ff = 0.0f;
    float emf_d, emf_q, emf;
    bool adapt = false, locked;

    if (m->n > 0u) {
        float i_d, i_q, psi_ex;
        const float sg = m->reverse ? -1.0f : 1.0f; /* the rotor's dq from the frame's */
        mras_model_error(c, m->i_al_prev, m->i_be_prev, in->i_alpha_a, in->i_beta_a, in->u_alpha_v,
                         in->u_beta_v, theta_prev, w, &e_d, &e_q);
        tf_park(in->i_alpha_a, in->i_beta_a, cosf(m->theta_rad), sinf(m->theta_rad), &i_d, &i_q);
        i_d *= sg;
        i_q *= sg;
        psi_ex = c->psi_f_wb + (c->l_d_h - c->l_q_h) * i_d;
        if (!(psi_ex > 0.05f * c->psi_f_wb)) {
            psi_ex = 0.05f * c->psi_f_wb;
        }
        /* torque feed-forward: the acceleration the measured current gives (electrical) */
        a_ff = m->ff_gain * (c->psi_f_wb + (c->l_d_h - c->l_q_h) * i_d) * i_q;
        {
            /* the model's increment was turned by -w Ts / 2 into the frame of k: turn the error
             * back before reading the EMF from it */
            const float h = 0.5f * w * ts;
            emf_d = (e_d - h * e_q) * c->l_d_h / ts;
            emf_q = w * psi_ex - (e_q + h * e_d) * c->l_q_h / ts;
        }
        emf = sqrtf(emf_d * emf_d + emf_q * emf_q);
        if (emf == emf) {
            m->emf_f += a_f * (emf - m->emf_f);
        }
        if (emf == emf && a_ff == a_ff && m->emf_f > w_min * psi_ex) {
            /* the EMF phasor's angle in the model's frame (gain independent of speed) */
            eps = atan2f(emf_d, emf_q);
            const float w_hat = fabsf(m->omega_i_rad_s);
            ratio = emf / (psi_ex * (w_hat > w_min ? w_hat : w_min));
            adapt = true;
        }
    }
    m->eps_f += a_f * (eps - m->eps_f);
    m->e_w_f += a_f * (ratio - m->e_w_f);
    {
        /* lock with hysteresis: gained within the bounds, lost beyond 1.5 times them */
        const float k = m->locked ? 1.5f : 1.0f;
        locked = fabsf(m->omega_i_rad_s) >= w_min && (float)m->n * ts > 4.0f / c->bw_rad_s &&
                 fabsf(m->eps_f) < k * MRAS_LOCK_EPS &&
                 fabsf(m->e_w_f - 1.0f) < k * MRAS_LOCK_EMF_REL;
        m->locked = locked;
    }

    /* Adaptation (Popov's PI on the error, paper B (20), here with the torque feed-forward and a
     * load-acceleration state: poles at -bw, -bw, -bw); held while the EMF is below the range */
    {
        const float w_max = c->max_speed_rad_s;
        if (adapt) {
            m->omega_i_rad_s =
                clampf(m->omega_i_rad_s + ts * (a_ff + m->acc_rad_s2 + m->l2 * eps), -w_max, w_max);
            m->acc_rad_s2 = clampf(m->acc_rad_s2 + ts * m->l3 * eps, -MRAS_ACC_MAX, MRAS_ACC_MAX);
            m->omega_rad_s = clampf(m->omega_i_rad_s + m->l1 * eps, -w_max, w_max);
        } else {
            m->omega_rad_s = m->omega_i_rad_s;
        }
    }
    /* theta_hat(k): the model's frame tracks the EMF phasor, whose q axis is the rotor's for
     * w > 0 and its opposite for w < 0 (hysteresis around standstill) */
    if (m->omega_i_rad_s > 0.5f * w_min) {
        m->reverse = false;
    } else if (m->omega_i_rad_s < -0.5f * w_min) {
        m->reverse = true;
    }
    out->theta_e_rad = m->reverse ? tf_wrap_2pi(m->theta_rad + FW_PI_F) : m->theta_rad;
    m->theta_rad = tf_wrap_2pi(m->theta_rad + m->omega_rad_s * ts);
    m->i_al_prev = in->i_alpha_a;
    m->i_be_prev = in->i_beta_a;
    m->n++;

    out->omega_e_rad_s = m->omega_i_rad_s;
    out->eps_rad = eps;
    out->locked = locked;
    {
        const float q1 = fabsf(m->eps_f) / (2.0f * MRAS_LOCK_EPS);
        const float q2 = fabsf(m->e_w_f - 1.0f) / (2.0f * MRAS_LOCK_EMF_REL);
        out->confidence = fabsf(m->omega_i_rad_s) >= w_min
                              ? clampf(1.0f - (q1 > q2 ? q1 : q2), 0.0f, 1.0f)
                              : 0.0f;
    }
}
