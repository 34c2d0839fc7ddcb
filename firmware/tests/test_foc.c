/* Unit tests of the FOC occupant (foc.h): the current loop tracks a step with the bandwidth it was
 * designed for (first order, 63 % at 1/bw plus the computation delay), decoupling at speed, the
 * voltage limit with anti-windup, and SVPWM duties. Plant: paper B's surface PMSM in dq, fine
 * Euler steps, the inverter as averaged PWM, one period of computation delay. */
#include "check.h"

#include <string.h>

#include "foc.h"
#include "transforms.h"

#define TS    100e-6
#define R_OHM 2.875
#define L_H   8.5e-3
#define PSI   0.175
#define VDC   311.0

typedef struct {
    double i_d, i_q, theta, w;
    double d_next[3], d_now[3]; /* duties decided last period (applied next) and now applied */
} rig_t;

/* one period of the plant with the applied duties, rotor at constant speed w */
static void plant_period(rig_t *p)
{
    const int n = 400;
    const double h = TS / n;
    const double va = VDC * p->d_now[0], vb = VDC * p->d_now[1], vc = VDC * p->d_now[2];
    const double u_al = (2.0 * va - vb - vc) / 3.0, u_be = (vb - vc) / sqrt(3.0);
    int k;
    for (k = 0; k < n; k++) {
        const double c = cos(p->theta), s = sin(p->theta);
        const double u_d = c * u_al + s * u_be, u_q = -s * u_al + c * u_be;
        const double did = (u_d - R_OHM * p->i_d + p->w * L_H * p->i_q) / L_H;
        const double diq = (u_q - R_OHM * p->i_q - p->w * L_H * p->i_d - p->w * PSI) / L_H;
        p->i_d += h * did;
        p->i_q += h * diq;
        p->theta += h * p->w;
    }
}

/* n periods of control: returns i_d, i_q after each in out_d/out_q */
static void run(foc_t *f, rig_t *p, int n, float id_ref, float iq_ref, double *out_d, double *out_q,
                foc_out_t *last)
{
    int k;
    for (k = 0; k < n; k++) {
        foc_in_t in;
        foc_out_t o;
        in.i_d_a = (float)p->i_d;
        in.i_q_a = (float)p->i_q;
        in.i_d_ref_a = id_ref;
        in.i_q_ref_a = iq_ref;
        in.cos_theta = (float)cos(p->theta);
        in.sin_theta = (float)sin(p->theta);
        in.omega_e_rad_s = (float)p->w;
        in.v_dc_v = (float)VDC;
        in.r_s_ohm = (float)R_OHM;
        in.l_d_h = (float)L_H;
        in.l_q_h = (float)L_H;
        in.psi_f_wb = (float)PSI;
        foc_step(f, &in, &o);
        /* the board applies the previous command during this period */
        memcpy(p->d_now, p->d_next, sizeof p->d_now);
        p->d_next[0] = o.duty_a;
        p->d_next[1] = o.duty_b;
        p->d_next[2] = o.duty_c;
        plant_period(p);
        out_d[k] = p->i_d;
        out_q[k] = p->i_q;
        if (last) {
            *last = o;
        }
    }
}

static void rig_init(rig_t *p, double w)
{
    memset(p, 0, sizeof *p);
    p->w = w;
    p->theta = 0.3;
    p->d_next[0] = p->d_next[1] = p->d_next[2] = 0.5;
    p->d_now[0] = p->d_now[1] = p->d_now[2] = 0.5;
}

static void test_step_bandwidth(void)
{
    const float bws[2] = { 1000.0f, 3141.6f };
    int b;
    for (b = 0; b < 2; b++) {
        foc_cfg_t cfg;
        foc_t f;
        rig_t p;
        double id[400], iq[400], t63 = -1.0, peak = 0.0;
        int k;
        foc_cfg_default(&cfg);
        cfg.ts_s = (float)TS;
        cfg.bw_rad_s = bws[b];
        foc_init(&f, &cfg);
        rig_init(&p, 0.0); /* locked rotor */
        run(&f, &p, 400, 2.0f, 0.0f, id, iq, NULL);
        for (k = 0; k < 400; k++) {
            if (t63 < 0.0 && id[k] >= 2.0 * (1.0 - exp(-1.0))) {
                /* linear interpolation between the samples */
                const double prev = k > 0 ? id[k - 1] : 0.0;
                t63 = TS * (k + (2.0 * (1.0 - exp(-1.0)) - prev) / (id[k] - prev));
            }
            if (id[k] > peak) {
                peak = id[k];
            }
        }
        printf("  bw %.0f rad/s: 63 %% after %.0f us (1/bw = %.0f us), overshoot %.1f %%\n",
               (double)bws[b], t63 * 1e6, 1e6 / (double)bws[b], 100.0 * (peak / 2.0 - 1.0));
        CHECK(t63 > 0.8 / (double)bws[b] && t63 < 1.0 / (double)bws[b] + 2.5 * TS,
              "foc: 63 % of the step within 1/bw plus the delay");
        CHECK(peak < 2.0 * 1.1, "foc: overshoot below 10 %");
        CHECK(fabs(id[399] - 2.0) < 0.01, "foc: no steady-state error");
        CHECK(fabs(iq[399]) < 0.01, "foc: the q axis stays at zero");
    }
}

static void test_decoupling_at_speed(void)
{
    foc_cfg_t cfg;
    foc_t f;
    rig_t p;
    double id[600], iq[600], worst_d = 0.0;
    int k;
    foc_cfg_default(&cfg);
    cfg.ts_s = (float)TS;
    foc_init(&f, &cfg);
    rig_init(&p, 628.3); /* 1500 r/min */
    run(&f, &p, 300, 0.0f, 0.0f, id, iq, NULL);
    CHECK(fabs(id[299]) < 0.05 && fabs(iq[299]) < 0.05, "foc: holds zero current at speed");
    run(&f, &p, 600, 0.0f, 4.0f, id, iq, NULL);
    for (k = 0; k < 600; k++) {
        if (fabs(id[k]) > worst_d) {
            worst_d = fabs(id[k]);
        }
    }
    printf("  1500 r/min, q step 0 -> 4 A: largest d excursion %.3f A, final i_q %.3f A\n", worst_d,
           iq[599]);
    CHECK(worst_d < 0.4, "foc: decoupling keeps the d axis within 10 % of a q step");
    CHECK(fabs(iq[599] - 4.0) < 0.02, "foc: q follows at speed");
}

static void test_limit_and_duties(void)
{
    foc_cfg_t cfg;
    foc_t f;
    rig_t p;
    double id[600], iq[600], peak = 0.0;
    foc_out_t o;
    int k, n_limited = 0;
    foc_cfg_default(&cfg);
    cfg.ts_s = (float)TS;
    foc_init(&f, &cfg);
    rig_init(&p, 628.3); /* 1500 r/min: 110 V of EMF, 180 V in the linear range */
    run(&f, &p, 200, 0.0f, 0.0f, id, iq, NULL);
    /* a 9 A step asks kp 9 A = 240 V on top of the EMF: the output saturates for a while */
    for (k = 0; k < 600; k++) {
        run(&f, &p, 1, 0.0f, 9.0f, &id[k], &iq[k], &o);
        n_limited += o.limited ? 1 : 0;
        if (iq[k] > peak) {
            peak = iq[k];
        }
        CHECK(o.duty_a >= 0.0f && o.duty_a <= 1.0f && o.duty_b >= 0.0f && o.duty_b <= 1.0f &&
                  o.duty_c >= 0.0f && o.duty_c <= 1.0f,
              "foc: duties within [0, 1]");
        CHECK(sqrtf(o.u_d_cmd_v * o.u_d_cmd_v + o.u_q_cmd_v * o.u_q_cmd_v) <=
                  (float)VDC * 0.57735027f + 0.01f,
              "foc: |u| within v_dc / sqrt(3)");
    }
    printf(
        "  1500 r/min, q step 0 -> 9 A: limited for %d periods, overshoot %.1f %%, final %.3f A\n",
        n_limited, 100.0 * (peak / 9.0 - 1.0), iq[599]);
    CHECK(n_limited >= 2, "foc: the step saturates the voltage");
    CHECK(peak < 9.0 * 1.05, "foc: anti-windup: overshoot below 5 % after saturation");
    CHECK(fabs(iq[599] - 9.0) < 0.05, "foc: and the current settles");
    {
        /* SVPWM: the duties' common mode is centred (min-max injection) */
        const float mx = fmaxf(o.duty_a, fmaxf(o.duty_b, o.duty_c));
        const float mn = fminf(o.duty_a, fminf(o.duty_b, o.duty_c));
        CHECK_NEAR(0.5f * (mx + mn), 0.5f, 1e-4, "foc: SVPWM centres the duties");
    }
}

int main(void)
{
    test_step_bandwidth();
    test_decoupling_at_speed();
    test_limit_and_duties();
    return CHECK_DONE();
}
