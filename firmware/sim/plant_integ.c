/* The plant's integration over one period with a known voltage (RK4 sub-steps, plant_integ.h),
 * the end-of-period bookkeeping (angle, averages, thermal, sample-delay history), and the ideal
 * rotor-frame voltage source (plant_step_udq). */
#include "plant_integ.h"

#include <math.h>

/* true phase currents at the period boundaries, for the sample delay */
static void hist_push(plant_t *p)
{
    p->hist_pos = (p->hist_pos + 1u) & (PLANT_DELAY_RING - 1u);
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, p->hist_i[p->hist_pos]);
}

void pl_hist_fill(plant_t *p)
{
    int n;
    for (n = 0; n < PLANT_DELAY_RING; n++) {
        hist_push(p);
    }
}

/* store the period's end state; cos/sin of the electrical angle are carried incrementally
 * (renormalised every period) and recomputed from theta_m every 256 periods */
void pl_finish_period(plant_t *p, const ctx_t *k, const xs_t *x, double th_tot, double aud,
                      double auq)
{
    p->i_d_a = x->id;
    p->i_q_a = x->iq;
    p->omega_m_rad_s = x->w;
    p->theta_m_rad = wrap_2pi(p->theta_m_rad + th_tot);
    p->n_periods++;
    if ((p->n_periods & 255u) == 0u) {
        const double the = (double)p->cfg.pole_pairs * p->theta_m_rad;
        p->cos_e = cos(the);
        p->sin_e = sin(the);
    } else {
        const double r = 1.5 - 0.5 * (k->c0 * k->c0 + k->s0 * k->s0);
        p->cos_e = k->c0 * r;
        p->sin_e = k->s0 * r;
    }
    p->u_d_avg_v = aud * p->inv_ts;
    p->u_q_avg_v = auq * p->inv_ts;
    if (p->cfg.thermal_on) {
        p->th_acc_w += 1.5 * p->r_s_ohm * (x->id * x->id + x->iq * x->iq);
        if (++p->th_n >= PLANT_THERMAL_DIV) {
            pl_thermal_step(p);
        }
    }
    if (p->delay_n >= 0) {
        hist_push(p);
    }
    if (p->cfg.map != NULL) {
        pl_apparent_ld_step(p);
    }
}

void pl_ctx_start(const plant_t *p, ctx_t *k, xs_t *x, double t_load)
{
    k->c0 = p->cos_e;
    k->s0 = p->sin_e;
    k->u1 = 0.0;
    k->u2 = 0.0;
    k->t_load = t_load;
    k->fric = 0.0;
    k->t_cog = 0.0;
    k->frozen = p->hold_speed;
    k->blocked = -1;
    k->lam = 0.0;
    x->id = p->i_d_a;
    x->iq = p->i_q_a;
    x->w = p->omega_m_rad_s;
    x->th = 0.0;
}

PL_INLINE void advance_on_mm(plant_t *p, int mode, int mm, double u1, double u2, double t_load)
{
    ctx_t k;
    xs_t x;
    double aud = 0.0, auq = 0.0, th_tot = 0.0;
    const double h = p->h_s;
    int n;

    pl_ctx_start(p, &k, &x, t_load);
    k.u1 = u1;
    k.u2 = u2;
    for (n = 0; n < p->cfg.substeps; n++) {
        mech_mode(p, &k, &x, mm);
        if (mm && p->cfg.map != NULL) { /* a flux map: integrated in the flux linkage */
            if (mode == MODE_UDQ) {
                rk4_lam(p, &k, &x, h, MODE_UDQ, &aud, &auq, &th_tot);
            } else {
                rk4_lam(p, &k, &x, h, MODE_KNOWN, &aud, &auq, &th_tot);
            }
        } else if (mode == MODE_UDQ) {
            rk4(p, &k, &x, h, MODE_UDQ, mm, &aud, &auq, &th_tot);
        } else {
            rk4(p, &k, &x, h, MODE_KNOWN, mm, &aud, &auq, &th_tot);
        }
        mech_clamp(&k, &x);
    }
    p->diodes_valid = false;
    p->load_nm = t_load;
    pl_finish_period(p, &k, &x, th_tot, aud, auq);
}

/* one branch per period: the magnetics with effects, or the linear machine */
void pl_advance_on(plant_t *p, int mode, double u1, double u2, double t_load)
{
    if (p->mag_general) {
        advance_on_mm(p, mode, 1, u1, u2, t_load);
    } else {
        advance_on_mm(p, mode, 0, u1, u2, t_load);
    }
}

void plant_step_udq(plant_t *p, double u_d_v, double u_q_v, double load_nm)
{
    pl_advance_on(p, MODE_UDQ, u_d_v, u_q_v, load_nm);
    p->pwm_prev = false; /* not an inverter: no switch history */
}
