/* The plant's inverter: leg distortion (dead time, device drop), switch states or averaged PWM
 * duties around one period (PWM-update delay, DC link), and PWM off (the diode bridge with
 * current-zero events). */
#include "plant_integ.h"

#include <math.h>

/* ------------------------------------------------------------------ leg distortion (effect seam) */

PL_INLINE double leg_dist(const plant_t *p, double i, double rise, double fall, double k_dt_v)
{
    double sg;
    if (p->inv_i_dt <= 0.0) {
        return 0.0;
    }
    sg = sigm(i * p->inv_i_dt);
    /* rise (0 -> 1): the upper switch turns on t_d late; meanwhile i > 0 keeps the lower diode on (volts lost).
     * fall (1 -> 0): the lower switch turns on t_d late; meanwhile i < 0 keeps the upper diode on (volts gained).
     * sigma replaces the ideal sign: a small current cannot swing the leg within the dead time. */
    return -p->cfg.v_drop_v * sg - k_dt_v * (rise * 0.5 * (1.0 + sg) - fall * 0.5 * (1.0 - sg));
}

double plant_leg_distortion_v(const plant_t *p, double i_a, int transition)
{
    const double rise = (transition == 1 || transition == 2) ? 1.0 : 0.0;
    const double fall = (transition == -1 || transition == 2) ? 1.0 : 0.0;
    return leg_dist(p, i_a, rise, fall, p->v_dc_v * p->cfg.dead_time_s / p->cfg.ts_s);
}

/* ------------------------------------------------------------------ PWM off: diode bridge */

/* open phase b: set i_b = 0 exactly by removing the current's component along g = R(-theta_e) e_b;
 * if the remaining pair no longer flows in its diodes' direction, everything is open */
static void block_phase(plant_t *p, const ctx_t *k, xs_t *x, int b)
{
    const double gd = k->c0 * EX[b] + k->s0 * EY[b], gq = -k->s0 * EX[b] + k->c0 * EY[b];
    const double ix = gd * x->id + gq * x->iq;
    double i3[3];
    int n, nblk = 0;
    x->id -= ix * gd;
    x->iq -= ix * gq;
    p->diode[b] = 0;
    phase_currents(k->c0, k->s0, x->id, x->iq, i3);
    for (n = 0; n < 3; n++) {
        if (p->diode[n] == 0 || (double)p->diode[n] * i3[n] <= 0.0) {
            nblk++;
        }
    }
    if (nblk >= 2) {
        x->id = 0.0;
        x->iq = 0.0;
        p->diode[0] = p->diode[1] = p->diode[2] = 0;
    }
}

/* known (stationary-frame) voltage of the conducting diodes; open terminals counted as 0 */
static void diode_voltage(const plant_t *p, double *ual, double *ube)
{
    double v[3];
    int n;
    for (n = 0; n < 3; n++) {
        v[n] = p->diode[n] > 0 ? -p->cfg.v_drop_v
                               : (p->diode[n] < 0 ? p->v_dc_v + p->cfg.v_drop_v : 0.0);
    }
    *ual = (2.0 * v[0] - v[1] - v[2]) * (1.0 / 3.0);
    *ube = (v[1] - v[2]) * PL_INV_SQRT3;
}

static int diode_mode(const plant_t *p, int *blocked)
{
    int n, nb = 0;
    *blocked = -1;
    for (n = 0; n < 3; n++) {
        if (p->diode[n] == 0) {
            nb++;
            *blocked = n;
        }
    }
    return nb == 0 ? MODE_KNOWN : (nb == 1 ? MODE_ONE_BLOCKED : MODE_ALL_BLOCKED);
}

/* an open phase (or pair) starts to conduct when its floating terminal would leave the DC rails */
static void diode_unblock(plant_t *p, ctx_t *k, const xs_t *x)
{
    const base_t b = { k->c0, k->s0, 0.0 };
    const double vd = p->cfg.v_drop_v;
    dx_t d;
    double eal, ebe, e3[3];
    int mode = diode_mode(p, &k->blocked), n, hi = 0, lo = 0;
    if (mode == MODE_KNOWN) {
        return;
    }
    diode_voltage(p, &k->u1, &k->u2);
    deriv(p, k, x, &d, mode, p->mag_general ? 1 : 0, &b, 1);
    if (mode == MODE_ONE_BLOCKED) {
        const double vx = 1.5 * k->lam; /* floating terminal voltage above DC- */
        if (vx > p->v_dc_v + vd) {
            p->diode[k->blocked] = -1;
        } else if (vx < -vd) {
            p->diode[k->blocked] = 1;
        }
        return;
    }
    /* all open: the terminals sit at the phase back-EMFs plus a common float */
    eal = k->c0 * d.ud - k->s0 * d.uq;
    ebe = k->s0 * d.ud + k->c0 * d.uq;
    for (n = 0; n < 3; n++) {
        e3[n] = EX[n] * eal + EY[n] * ebe;
        if (e3[n] > e3[hi]) {
            hi = n;
        }
        if (e3[n] < e3[lo]) {
            lo = n;
        }
    }
    if (e3[hi] - e3[lo] > p->v_dc_v + 2.0 * vd) {
        p->diode[hi] = -1; /* the highest back-EMF drives current out through the upper diode */
        p->diode[lo] = 1;
    }
}

/* PWM off for one period. Each phase is clamped by a diode to the rail that opposes its current
 * (i > 0: lower diode, terminal at -v_drop; i < 0: upper diode, v_dc + v_drop); a phase whose current
 * reaches zero opens (its terminal floats, its current stays zero); an open phase or pair conducts
 * again only if the back-EMF pushes its terminal beyond a rail (uncontrolled rectification). */
static void advance_off(plant_t *p, double t_load)
{
    ctx_t k;
    xs_t x, x0;
    double aud = 0.0, auq = 0.0, th_tot = 0.0;
    const int mm = p->mag_general ? 1 : 0;
    int n;

    pl_ctx_start(p, &k, &x, t_load);
    if (!p->diodes_valid) { /* switches just opened: each current keeps flowing through the opposite diode */
        double i3[3];
        int b = -1, nb = 0;
        phase_currents(k.c0, k.s0, x.id, x.iq, i3);
        for (n = 0; n < 3; n++) {
            p->diode[n] = (int8_t)(i3[n] > 1e-9 ? 1 : (i3[n] < -1e-9 ? -1 : 0));
            if (p->diode[n] == 0) {
                nb++;
                b = n;
            }
        }
        if (nb == 1) {
            block_phase(p, &k, &x, b);
        } else if (nb > 1) {
            x.id = x.iq = 0.0;
            p->diode[0] = p->diode[1] = p->diode[2] = 0;
        }
    }

    for (n = 0; n < p->cfg.substeps; n++) {
        double rem = p->h_s;
        int iter;
        for (iter = 0; iter < 8 && rem > 0.0; iter++) {
            const double aud0 = aud, auq0 = auq, th0 = th_tot, c0 = k.c0, s0 = k.s0;
            double frac = 2.0, i0[3], i1[3];
            int mode, y, ev = -1;
            diode_unblock(p, &k, &x);
            mode = diode_mode(p, &k.blocked);
            diode_voltage(p, &k.u1, &k.u2);
            mech_mode(p, &k, &x, mm);
            x0 = x;
            phase_currents(k.c0, k.s0, x.id, x.iq, i0);
            rk4(p, &k, &x, rem, mode, mm, &aud, &auq, &th_tot);
            if (mode != MODE_ALL_BLOCKED && iter < 7) {
                phase_currents(k.c0, k.s0, x.id, x.iq, i1);
                for (y = 0; y < 3; y++) {
                    const double a0 = (double)p->diode[y] * i0[y], a1 = (double)p->diode[y] * i1[y];
                    if (p->diode[y] != 0 && a1 <= 0.0) {
                        const double f = a0 > 0.0 ? a0 / (a0 - a1) : 0.0;
                        if (f < frac) {
                            frac = f;
                            ev = y;
                        }
                    }
                }
            }
            if (ev < 0) { /* no current zero inside the piece (or the last try): accept it */
                if (mode != MODE_ALL_BLOCKED) {
                    phase_currents(k.c0, k.s0, x.id, x.iq, i1);
                    for (y = 0; y < 3; y++) {
                        if (p->diode[y] != 0 && (double)p->diode[y] * i1[y] <= 0.0) {
                            block_phase(p, &k, &x, y);
                            break;
                        }
                    }
                }
                mech_clamp(&k, &x);
                break;
            }
            /* a conducting current reaches zero inside the piece: redo the piece up to the zero
             * (linear interpolation of the crossing), open that phase, go on with the rest */
            x = x0;
            aud = aud0;
            auq = auq0;
            th_tot = th0;
            k.c0 = c0;
            k.s0 = s0;
            if (frac > 0.0) {
                rk4(p, &k, &x, frac * rem, mode, mm, &aud, &auq, &th_tot);
                mech_clamp(&k, &x);
            }
            block_phase(p, &k, &x, ev);
            rem -= frac * rem;
        }
    }
    p->diodes_valid = true;
    p->load_nm = t_load;
    pl_finish_period(p, &k, &x, th_tot, aud, auq);
}

/* ------------------------------------------------------------------ one period of the legs */

static void step_legs_now(plant_t *p, const double d[3], bool pwm_on, bool carrier, double t_load);

/* the PWM-update delay (whole periods) and the DC link around one period of the inverter */
void pl_step_legs(plant_t *p, const double d_in[3], bool on_in, bool carrier_in, double t_load)
{
    const double *d = d_in;
    bool pwm_on = on_in, carrier = carrier_in;
    double i0[3];
    if (p->cfg.pwm_delay_periods > 0) {
        const uint32_t w = p->fifo_pos,
                       r = (w - (uint32_t)p->cfg.pwm_delay_periods) & (PLANT_DELAY_RING - 1u);
        p->fifo_d[w][0] = d_in[0];
        p->fifo_d[w][1] = d_in[1];
        p->fifo_d[w][2] = d_in[2];
        p->fifo_on[w] = on_in;
        p->fifo_carrier[w] = carrier_in;
        p->fifo_pos = (w + 1u) & (PLANT_DELAY_RING - 1u);
        d = p->fifo_d[r];
        pwm_on = p->fifo_on[r];
        carrier = p->fifo_carrier[r];
    }
    if (!p->cfg.dc_on) {
        step_legs_now(p, d, pwm_on, carrier, t_load);
        return;
    }
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i0);
    step_legs_now(p, d, pwm_on, carrier, t_load);
    pl_dc_link_step(p, d, pwm_on, i0);
}

/* switching (d = 0 or 1, held over the period, transitions at the period start) or averaged PWM
 * (carrier: 0 < d < 1 means one rising and one falling edge in the period) */
static void step_legs_now(plant_t *p, const double d[3], bool pwm_on, bool carrier, double t_load)
{
    double i3[3], v[3], k_dt_v, was_on;
    int n;
    if (!pwm_on) {
        advance_off(p, t_load);
        p->pwm_prev = false;
        return;
    }
    k_dt_v = p->v_dc_v * p->cfg.dead_time_s / p->cfg.ts_s;
    was_on = p->pwm_prev ? 1.0 : 0.0;
    if (!p->dist_on) { /* ideal inverter */
        for (n = 0; n < 3; n++) {
            v[n] = p->v_dc_v * d[n];
            p->s_prev[n] = (uint16_t)(d[n] > 0.5);
        }
        pl_advance_on(p, MODE_KNOWN, (2.0 * v[0] - v[1] - v[2]) * (1.0 / 3.0),
                      (v[1] - v[2]) * PL_INV_SQRT3, t_load);
        p->pwm_prev = true;
        return;
    }
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i3);
    for (n = 0; n < 3; n++) {
        double rise, fall;
        if (carrier) {
            rise = fall = (d[n] > 0.0 && d[n] < 1.0) ? 1.0 : 0.0;
        } else { /* arithmetic, not branches: FCS switch sequences are unpredictable */
            const double sp = (double)p->s_prev[n];
            rise = was_on * d[n] * (1.0 - sp);
            fall = was_on * sp * (1.0 - d[n]);
        }
        p->v_dist_v[n] = leg_dist(p, i3[n], rise, fall, k_dt_v);
        v[n] = p->v_dc_v * d[n] + p->v_dist_v[n];
        p->s_prev[n] = (uint16_t)(d[n] > 0.5);
    }
    pl_advance_on(p, MODE_KNOWN, (2.0 * v[0] - v[1] - v[2]) * (1.0 / 3.0),
                  (v[1] - v[2]) * PL_INV_SQRT3, t_load);
    p->pwm_prev = true;
}

void plant_step(plant_t *p, const fw_cmd_t *cmd)
{
    double d[3];
    if (cmd->mode == FW_CMD_DUTIES) { /* a modulator's duties: averaged PWM */
        d[0] = (double)cmd->duty_a;
        d[1] = (double)cmd->duty_b;
        d[2] = (double)cmd->duty_c;
        plant_step_duty(p, d, cmd->pwm_on, (double)cmd->load_nm);
        return;
    }
    d[0] = (double)(cmd->s_a != 0);
    d[1] = (double)(cmd->s_b != 0);
    d[2] = (double)(cmd->s_c != 0);
    pl_step_legs(p, d, cmd->pwm_on, false, (double)cmd->load_nm);
}

void plant_step_duty(plant_t *p, const double duty[3], bool pwm_on, double load_nm)
{
    double d[3];
    int n;
    for (n = 0; n < 3; n++) {
        d[n] = duty[n] < 0.0 ? 0.0 : (duty[n] > 1.0 ? 1.0 : duty[n]);
    }
    pl_step_legs(p, d, pwm_on, true, load_nm);
}
