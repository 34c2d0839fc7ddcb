/* Unit tests of the MRAS angle estimator (mras.h): the model error's sign and magnitude against a
 * hand-computed case, and convergence from a wrong initial angle on an ideal surface PMSM. */
#include "check.h"

#include <string.h>

#include "mras.h"
#include "transforms.h"

#ifndef MRAS_TEST_STEPS
#define MRAS_TEST_STEPS 5000
#endif

/* Paper B's surface PMSM at 10 kHz. */
static mras_cfg_t cfg_b(void)
{
    mras_cfg_t c;
    memset(&c, 0, sizeof c);
    c.ts_s = 100e-6f;
    c.bw_rad_s = 300.0f;
    c.min_speed_rad_s = 31.4f;
    c.max_speed_rad_s = 760.0f;
    c.r_s_ohm = 2.875f;
    c.l_d_h = 8.5e-3f;
    c.l_q_h = 8.5e-3f;
    c.psi_f_wb = 0.175f;
    return c;
}

/* Ideal surface PMSM in the stationary frame, one period of Ts in fine Euler steps at constant
 * speed w with a constant stationary voltage: L di/dt = u - R i - j w psi e^{j theta}. */
static void plant_period(const mras_cfg_t *c, double *i_al, double *i_be, double *theta, double w,
                         double u_al, double u_be)
{
    const int n = 2000;
    const double h = (double)c->ts_s / n, l = (double)c->l_d_h, r = (double)c->r_s_ohm;
    const double psi = (double)c->psi_f_wb;
    int k;
    for (k = 0; k < n; k++) {
        const double th = *theta + 0.5 * w * h;
        const double e_al = -w * psi * sin(th), e_be = w * psi * cos(th);
        *i_al += h / l * (u_al - r * *i_al - e_al);
        *i_be += h / l * (u_be - r * *i_be - e_be);
        *theta += w * h;
    }
}

/* Hand-computed case: with the estimated frame d behind the rotor and the right speed, the
 * model error is e_d = Ts w psi / L sin d, e_q = Ts w psi / L (1 - cos d) (docs/sensorless.md). */
static void test_error_signal(void)
{
    const mras_cfg_t c = cfg_b();
    const double w = 628.3; /* 1500 r/min, p = 4 */
    const double k_a = (double)c.ts_s * w * (double)c.psi_f_wb / (double)c.l_d_h; /* 1.29 A */
    const double deltas[4] = { 0.3, -0.3, 0.05, 0.6 };
    int n;
    for (n = 0; n < 4; n++) {
        const double d = deltas[n];
        double tol;
        double i_al = 2.0, i_be = -1.0, th = 0.7;
        const double i_al0 = i_al, i_be0 = i_be, th0 = th;
        const double u_al = -40.0, u_be = 95.0; /* some voltage: the model accounts for it */
        float e_d, e_q;
        plant_period(&c, &i_al, &i_be, &th, w, u_al, u_be);
        mras_model_error(&c, (float)i_al0, (float)i_be0, (float)i_al, (float)i_be, (float)u_al,
                         (float)u_be, (float)(th0 - d), (float)w, &e_d, &e_q);
        /* first order in w Ts: 1 % of the scale for small d, 3 % at d = 0.6 rad */
        tol = (fabs(d) < 0.5 ? 0.01 : 0.03) * k_a;
        CHECK_NEAR(e_d, k_a * sin(d), tol, "mras: e_d = Ts w psi / L sin(d)");
        CHECK_NEAR(e_q, k_a * (1.0 - cos(d)), tol, "mras: e_q = Ts w psi / L (1 - cos d)");
    }
    {
        /* the sign: an estimate behind the rotor gives e_d > 0 (the adaptation speeds it up) */
        double i_al = 0.0, i_be = 0.0, th = 2.0;
        float e_d, e_q;
        plant_period(&c, &i_al, &i_be, &th, w, 0.0, 0.0);
        mras_model_error(&c, 0.0f, 0.0f, (float)i_al, (float)i_be, 0.0f, 0.0f, (float)(2.0 - 0.1),
                         (float)w, &e_d, &e_q);
        CHECK(e_d > 0.0f, "mras: an estimate behind the rotor reads a positive e_d");
        printf("  hand case d = 0.1 rad at 1500 r/min: e_d %.4f A (expected %.4f A)\n", (double)e_d,
               k_a * sin(0.1));
    }
}

/* Convergence: the rotor turns at w, the estimator starts d0 away (and at its initial speed 0);
 * run 0.5 s and check angle and speed. Voltage: the EMF plus a small d current's drop. */
static double run_converge(double w, double d0, double *speed_err)
{
    mras_cfg_t c = cfg_b();
    mras_t m;
    mras_in_t in;
    mras_out_t o;
    double i_al = 0.0, i_be = 0.0, th = 0.4, worst_late = 0.0;
    double u_al = 0.0, u_be = 0.0;
    int k;
    memset(&o, 0, sizeof o);
    c.theta0_rad = (float)(th - d0);
    mras_init(&m, &c);
    for (k = 0; k < MRAS_TEST_STEPS; k++) {
        double th_mid, err;
        in.i_alpha_a = (float)i_al;
        in.i_beta_a = (float)i_be;
        in.u_alpha_v = (float)u_al;
        in.u_beta_v = (float)u_be;
        mras_step(&m, &in, &o);
        err = tf_wrap_pi((float)(o.theta_e_rad - th));
        if (k > MRAS_TEST_STEPS - 1000 && fabs(err) > worst_late) {
            worst_late = fabs(err);
        }
        /* the voltage applied during [k, k+1): EMF at mid-period plus 1 A on d */
        th_mid = th + 0.5 * w * (double)c.ts_s;
        u_al = -w * (double)c.psi_f_wb * sin(th_mid) + (double)c.r_s_ohm * cos(th_mid);
        u_be = w * (double)c.psi_f_wb * cos(th_mid) + (double)c.r_s_ohm * sin(th_mid);
        plant_period(&c, &i_al, &i_be, &th, w, u_al, u_be);
    }
    *speed_err = (double)o.omega_e_rad_s - w;
    CHECK(o.locked, "mras: locked after converging");
    return worst_late;
}

static void test_converges(void)
{
    const double d0s[5] = { 1.5, -1.5, 2.5, -2.5, 0.8 };
    const double ws[4] = { 628.3, 251.3, -628.3, -100.0 };
    int i, j;
    for (j = 0; j < 4; j++) {
        for (i = 0; i < 5; i++) {
            double dw;
            const double err = run_converge(ws[j], d0s[i], &dw);
            CHECK(err < 0.01, "mras: converges from a wrong initial angle to within 0.01 rad");
            CHECK(fabs(dw) < 1.0, "mras: and to the right speed (within 1 rad/s)");
            if (i == 0 || err >= 0.01 || fabs(dw) >= 1.0) {
                printf("  w %.0f rad/s, initial error %.1f rad: angle error %.5f rad, speed error "
                       "%.3f rad/s over the last 0.1 s of 0.5 s\n",
                       ws[j], d0s[i], err, dw);
            }
        }
    }
}

int main(void)
{
    test_error_signal();
    test_converges();
    return CHECK_DONE();
}
