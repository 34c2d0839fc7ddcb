/* A sensorless current loop for the C tests: plant (sim/plant.h), MPCC on the estimated angle,
 * ripple PLL; the board's ordering (sample, control, then the plant advances one period with the
 * previous command). The rotor speed is imposed (an ideal dynamometer) unless free is set. */
#ifndef SENSORLESS_LOOP_H
#define SENSORLESS_LOOP_H

#include <math.h>
#include <string.h>

#include "dither.h"
#include "est_ripple_pll.h"
#include "mpcc.h"
#include "plant.h"
#include "transforms.h"

typedef struct {
    plant_t p;
    mpcc_t m;
    dither_t dith;
    rpll_t e;
    mpcc_out_t mo;
    rpll_out_t eo;
    fw_cmd_t cmd_prev;
    float th_used, w_used; /* the angle and speed the MPCC used in the last period */
    float i_d_ref_a, i_q_ref_a;
    float i_d_est_a;  /* d current in the estimated frame, this period */
    double th_true_k; /* the rotor's electrical angle at this period's sample */
} sl_t;

static inline void sl_cfg_pll(rpll_cfg_t *c)
{
    memset(c, 0, sizeof(*c));
    c->ts_s = 50e-6f;
    c->pole_pairs = 4u;
    c->r_s_ohm = 0.9f;
    c->l_d_h = 5e-3f;
    c->l_q_h = 12e-3f;
    c->psi_f_wb = 0.18f;
    c->j_kgm2 = 0.0036f;
    c->torque_ff = true;
    rerr_gamma_linear(&c->gamma, c->l_d_h, c->l_q_h);
}

/* theta_true_e: the rotor's electrical angle; theta_est_e: where the estimate starts. */
static inline void sl_init(sl_t *s, const plant_cfg_t *pc, const rpll_cfg_t *ec,
                           double theta_true_e, double omega_m, float theta_est_e)
{
    mpcc_cfg_t mc;
    memset(s, 0, sizeof(*s));
    plant_init(&s->p, pc);
    plant_set_mech(&s->p, theta_true_e / (double)pc->pole_pairs, omega_m, true);
    mpcc_cfg_default(&mc);
    mpcc_init(&s->m, &mc);
    {
        dither_cfg_t dc = { 22u, 0.6f }; /* as fw.c */
        dither_init(&s->dith, &dc);
    }
    rpll_init(&s->e, ec);
    rpll_reset(&s->e, theta_est_e, (float)(omega_m * (double)pc->pole_pairs));
    s->th_used = theta_est_e;
    s->w_used = (float)(omega_m * (double)pc->pole_pairs);
}

/* Electrical angle error, estimate minus truth, wrapped to (-pi, pi]. */
static inline double sl_err(const sl_t *s)
{
    double d = fmod((double)s->th_used - s->th_true_k, 2.0 * 3.14159265358979323846);
    if (d > 3.14159265358979323846) {
        d -= 2.0 * 3.14159265358979323846;
    } else if (d <= -3.14159265358979323846) {
        d += 2.0 * 3.14159265358979323846;
    }
    return d;
}

static inline void sl_period(sl_t *s)
{
    fw_meas_t meas;
    rpll_in_t in;
    mpcc_in_t mi;
    float c, sn, ua, ub, th_mid;
    fw_cmd_t cmd;
    plant_sample(&s->p, &meas);
    s->th_true_k = s->p.theta_m_rad * (double)s->p.cfg.pole_pairs;
    tf_clarke2(meas.i_a_a, meas.i_b_a, &in.i_alpha_a, &in.i_beta_a);
    th_mid = s->th_used + 0.5f * s->w_used * 50e-6f;
    tf_inv_park(s->mo.u_d_avg_v, s->mo.u_q_avg_v, cosf(th_mid), sinf(th_mid), &ua, &ub);
    in.u_alpha_v = ua;
    in.u_beta_v = ub;
    in.u_valid = true;
    rpll_step(&s->e, &in, &s->eo);
    s->th_used = s->eo.theta_e_rad;
    s->w_used = s->eo.omega_e_rad_s;
    c = cosf(s->th_used);
    sn = sinf(s->th_used);
    memset(&mi, 0, sizeof mi);
    tf_park(in.i_alpha_a, in.i_beta_a, c, sn, &mi.i_d_a, &mi.i_q_a);
    s->i_d_est_a = mi.i_d_a;
    mi.i_d_ref_a = s->i_d_ref_a + s->eo.i_d_excite_a;
    mi.i_q_ref_a = s->i_q_ref_a + dither_step(&s->dith, 0.6666667f * 540.0f * 50e-6f / 12e-3f);
    mi.theta_e_rad = s->th_used;
    mi.omega_e_rad_s = s->w_used;
    mi.v_dc_v = meas.v_dc_v;
    mi.r_s_ohm = 0.9f;
    mi.l_d_h = 5e-3f;
    mi.l_q_h = 12e-3f;
    mi.psi_f_wb = 0.18f;
    mpcc_step_cs(&s->m, &mi, c, sn, &s->mo);
    memset(&cmd, 0, sizeof cmd);
    cmd.mode = FW_CMD_STATES;
    cmd.s_a = s->mo.s_a;
    cmd.s_b = s->mo.s_b;
    cmd.s_c = s->mo.s_c;
    cmd.pwm_on = true;
    plant_step(&s->p, &s->cmd_prev);
    s->cmd_prev = cmd;
}

#endif
