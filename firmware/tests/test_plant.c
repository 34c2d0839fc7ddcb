/* Unit tests of the emulator's plant (firmware/sim/plant*.c): steady state, energy, integration,
 * inverter distortion. PWM off and mechanics: test_plant_mech.c; sensors, encoder and the PRNG:
 * test_plant_sensors.c. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "plant.h"
#include "plant_cmd.h"
#include "rng.h"

#define PI     3.14159265358979323846
#define TWO_PI (2.0 * PI)
#define SQRT3  1.7320508075688772

static double maxd(double a, double b)
{
    return a > b ? a : b;
}

/* ------------------------------------------------------------------ steady state */

static void test_steady_state(void)
{
    plant_cfg_t cfg;
    plant_t p;
    plant_truth_t t;
    const double wm = 100.0, id = -3.0, iq = 8.0;
    double we, ud, uq;
    int k;

    cfg_base(&cfg);
    CHECK(plant_cfg_check(&cfg) == NULL, "default config is valid");
    plant_init(&p, &cfg);
    plant_set_mech(&p, 0.4, wm, true);
    we = cfg.pole_pairs * wm;
    ud = cfg.r_s_ohm * id - we * cfg.l_q_h * iq; /* steady-state voltage equations */
    uq = cfg.r_s_ohm * iq + we * (cfg.l_d_h * id + cfg.psi_f_wb);
    for (k = 0; k < 8000; k++) { /* 0.4 s = 30 q-axis time constants */
        plant_step_udq(&p, ud, uq, 0.0);
    }
    plant_truth(&p, &t);
    CHECK_NEAR(t.i_d_a, id, 1e-6, "steady state i_d at 955 r/min");
    CHECK_NEAR(t.i_q_a, iq, 1e-6, "steady state i_q at 955 r/min");
    CHECK_NEAR(t.u_d_v, ud, 1e-9, "truth u_d is the applied voltage");
    CHECK_NEAR(t.u_q_v, uq, 1e-9, "truth u_q is the applied voltage");
    CHECK_NEAR(t.torque_nm, 1.5 * 4 * (0.18 * iq + (5e-3 - 12e-3) * id * iq), 1e-5,
               "torque formula");
    CHECK_NEAR(t.omega_m_rad_s, wm, 0.0, "held speed stays");
    CHECK_NEAR(t.theta_m_rad, fmod(0.4 + wm * 8000 * 50e-6, TWO_PI), 1e-9,
               "angle = integral of the held speed");
    CHECK_NEAR(t.t_s, 0.4, 1e-12, "truth time");

    /* the inverter path: switch state (1,0,0) held at standstill, rotor at theta_m = 0.3 */
    cfg.v_dc_v = 9.0;
    plant_init(&p, &cfg);
    plant_set_mech(&p, 0.3, 0.0, true);
    {
        fw_cmd_t c;
        const double the = 4 * 0.3, ua = 2.0 / 3.0 * 9.0;
        cmd_set(&c, 1, 0, 0, true, 0.0);
        for (k = 0; k < 8000; k++) {
            plant_step(&p, &c);
        }
        plant_truth(&p, &t);
        CHECK_NEAR(t.i_d_a, cos(the) * ua / 0.9, 1e-6,
                   "switch state (1,0,0): steady i_d = u_d / R");
        CHECK_NEAR(t.i_q_a, -sin(the) * ua / 0.9, 1e-6,
                   "switch state (1,0,0): steady i_q = u_q / R");
        CHECK_NEAR(t.i_a_a, ua / 0.9, 1e-6, "switch state (1,0,0): i_a = 2/3 v_dc / R");
        CHECK_NEAR(t.i_b_a, -0.5 * ua / 0.9, 1e-6, "switch state (1,0,0): i_b = -i_a / 2");
    }

    /* averaged PWM: duties (0.6, 0.4, 0.4) at theta_e = 0: u_d = 2/3 (0.6 - 0.4) v_dc */
    plant_init(&p, &cfg);
    {
        const double duty[3] = { 0.6, 0.4, 0.4 };
        for (k = 0; k < 8000; k++) {
            plant_step_duty(&p, duty, true, 0.0);
        }
        plant_truth(&p, &t);
        CHECK_NEAR(t.i_d_a, 2.0 / 3.0 * 0.2 * 9.0 / 0.9, 1e-6, "duty PWM: steady i_d");
        CHECK_NEAR(t.i_q_a, 0.0, 1e-9, "duty PWM: i_q = 0");
    }

    /* the board's command in duty mode takes the same path as plant_step_duty, bit for bit; duties
     * of exactly 0 and 1 on an ideal inverter are the switch states */
    {
        plant_t q, s;
        plant_truth_t tq, ts;
        fw_cmd_t c;
        const double duty[3] = { (double)0.7f, (double)0.25f,
                                 (double)0.4f }; /* the command's floats */
        plant_init(&p, &cfg);
        plant_init(&q, &cfg);
        memset(&c, 0, sizeof c);
        c.mode = FW_CMD_DUTIES;
        c.duty_a = 0.7f;
        c.duty_b = 0.25f;
        c.duty_c = 0.4f;
        c.pwm_on = true;
        for (k = 0; k < 200; k++) {
            plant_step(&p, &c);
            plant_step_duty(&q, duty, true, 0.0);
        }
        plant_truth(&p, &t);
        plant_truth(&q, &tq);
        CHECK(t.i_d_a == tq.i_d_a && t.i_q_a == tq.i_q_a && t.u_d_v == tq.u_d_v,
              "duty command: plant_step applies the duties as plant_step_duty does");
        plant_init(&p, &cfg);
        plant_init(&s, &cfg);
        for (k = 0; k < 200; k++) {
            fw_cmd_t st;
            cmd_set(&st, k % 3 == 0, k % 2, k % 5 == 1, true, 0.0);
            c.duty_a = (float)st.s_a;
            c.duty_b = (float)st.s_b;
            c.duty_c = (float)st.s_c;
            plant_step(&p, &c);
            plant_step(&s, &st);
        }
        plant_truth(&p, &t);
        plant_truth(&s, &ts);
        CHECK(t.i_d_a == ts.i_d_a && t.i_q_a == ts.i_q_a,
              "duty command: duties 0 and 1 on the ideal inverter equal the switch states");
    }
}

/* ------------------------------------------------------------------ energy and torque */

static void test_energy(void)
{
    plant_cfg_t cfg;
    plant_t p;
    plant_truth_t t0, t1;
    const double ud = -40.0, uq = 120.0, b = 0.002;
    double e_in = 0.0, e_cu = 0.0, e_visc = 0.0, w_mag0, w_mag1, ke0, ke1, p_in0, p_cu0, p_v0, bal;
    int k;

    cfg_base(&cfg);
    cfg.ts_s = 2e-6; /* fine periods so that the test's own trapezoid quadrature is exact enough */
    cfg.b_visc_nms = b;
    plant_init(&p, &cfg);
    plant_truth(&p, &t0);
    w_mag0 = 0.75 * (cfg.l_d_h * t0.i_d_a * t0.i_d_a + cfg.l_q_h * t0.i_q_a * t0.i_q_a);
    ke0 = 0.5 * cfg.j_kgm2 * t0.omega_m_rad_s * t0.omega_m_rad_s;
    p_in0 = 1.5 * (ud * t0.i_d_a + uq * t0.i_q_a);
    p_cu0 = 1.5 * cfg.r_s_ohm * (t0.i_d_a * t0.i_d_a + t0.i_q_a * t0.i_q_a);
    p_v0 = b * t0.omega_m_rad_s * t0.omega_m_rad_s;
    for (k = 0; k < 50000; k++) { /* 0.1 s: currents build up, the rotor accelerates */
        double p_in1, p_cu1, p_v1;
        plant_step_udq(&p, ud, uq, 0.0);
        plant_truth(&p, &t1);
        p_in1 = 1.5 * (ud * t1.i_d_a + uq * t1.i_q_a);
        p_cu1 = 1.5 * cfg.r_s_ohm * (t1.i_d_a * t1.i_d_a + t1.i_q_a * t1.i_q_a);
        p_v1 = b * t1.omega_m_rad_s * t1.omega_m_rad_s;
        e_in += 0.5 * cfg.ts_s * (p_in0 + p_in1);
        e_cu += 0.5 * cfg.ts_s * (p_cu0 + p_cu1);
        e_visc += 0.5 * cfg.ts_s * (p_v0 + p_v1);
        p_in0 = p_in1;
        p_cu0 = p_cu1;
        p_v0 = p_v1;
    }
    w_mag1 = 0.75 * (cfg.l_d_h * t1.i_d_a * t1.i_d_a + cfg.l_q_h * t1.i_q_a * t1.i_q_a);
    ke1 = 0.5 * cfg.j_kgm2 * t1.omega_m_rad_s * t1.omega_m_rad_s;
    bal = e_in - (e_cu + (w_mag1 - w_mag0) + (ke1 - ke0) + e_visc);
    printf("energy: in %.6g J, copper %.6g J, magnetic %.6g J, kinetic %.6g J, viscous %.6g J, "
           "residual %.3g J\n",
           e_in, e_cu, w_mag1 - w_mag0, ke1 - ke0, e_visc, bal);
    CHECK(t1.omega_m_rad_s > 5.0, "energy test: the rotor accelerated");
    CHECK(fabs(bal) < 1e-8 * e_in,
          "energy balance: electrical input = copper + magnetic + kinetic + viscous");
    CHECK(fabs(bal) < 1e-4 * (ke1 - ke0 + e_visc),
          "energy balance: the torque accounts for the mechanical energy");
    CHECK_NEAR(plant_torque(&p, -3.0, 8.0, 1.0),
               1.5 * 4 * (0.18 * 8.0 + (5e-3 - 12e-3) * -3.0 * 8.0), 1e-12,
               "plant_torque = 1.5 p (psi_f i_q + (Ld - Lq) i_d i_q)");
}

/* ------------------------------------------------------------------ RK4 accuracy */

/* independent reference: the same dq model integrated with RK4 and libm sin/cos at every stage */
typedef struct {
    double id, iq, w, th;
} ref_x;

static void ref_f(const plant_cfg_t *c, const ref_x *x, double ual, double ube, double tl, ref_x *d)
{
    const double the = c->pole_pairs * x->th, co = cos(the), si = sin(the),
                 we = c->pole_pairs * x->w;
    const double ud = co * ual + si * ube, uq = -si * ual + co * ube;
    d->id = (ud - c->r_s_ohm * x->id + we * c->l_q_h * x->iq) / c->l_d_h;
    d->iq = (uq - c->r_s_ohm * x->iq - we * (c->l_d_h * x->id + c->psi_f_wb)) / c->l_q_h;
    d->w = (1.5 * c->pole_pairs * (c->psi_f_wb * x->iq + (c->l_d_h - c->l_q_h) * x->id * x->iq) -
            tl - c->b_visc_nms * x->w) /
           c->j_kgm2;
    d->th = x->w;
}

static void ref_period(const plant_cfg_t *c, ref_x *x, int sa, int sb, int sc, double tl, int n)
{
    const double ual = c->v_dc_v * (2 * sa - sb - sc) / 3.0, ube = c->v_dc_v * (sb - sc) / SQRT3;
    const double h = c->ts_s / n;
    int k;
    for (k = 0; k < n; k++) {
        ref_x k1, k2, k3, k4, y;
        ref_f(c, x, ual, ube, tl, &k1);
        y.id = x->id + 0.5 * h * k1.id;
        y.iq = x->iq + 0.5 * h * k1.iq;
        y.w = x->w + 0.5 * h * k1.w;
        y.th = x->th + 0.5 * h * k1.th;
        ref_f(c, &y, ual, ube, tl, &k2);
        y.id = x->id + 0.5 * h * k2.id;
        y.iq = x->iq + 0.5 * h * k2.iq;
        y.w = x->w + 0.5 * h * k2.w;
        y.th = x->th + 0.5 * h * k2.th;
        ref_f(c, &y, ual, ube, tl, &k3);
        y.id = x->id + h * k3.id;
        y.iq = x->iq + h * k3.iq;
        y.w = x->w + h * k3.w;
        y.th = x->th + h * k3.th;
        ref_f(c, &y, ual, ube, tl, &k4);
        x->id += h / 6 * (k1.id + 2 * k2.id + 2 * k3.id + k4.id);
        x->iq += h / 6 * (k1.iq + 2 * k2.iq + 2 * k3.iq + k4.iq);
        x->w += h / 6 * (k1.w + 2 * k2.w + 2 * k3.w + k4.w);
        x->th += h / 6 * (k1.th + 2 * k2.th + 2 * k3.th + k4.th);
    }
}

#define ACC_N 2000
static uint8_t acc_seq[ACC_N];

/* switch state sequence of a bang-bang current loop (i_d* = -5 A, i_q* = 15 A) on the reference */
static void make_sequence(const plant_cfg_t *c, double w0)
{
    static const int sa[8] = { 0, 1, 1, 0, 0, 0, 1, 1 }, sb[8] = { 0, 0, 1, 1, 1, 0, 0, 1 },
                     sc[8] = { 0, 0, 0, 0, 1, 1, 1, 1 };
    ref_x x = { 0.0, 0.0, w0, 0.0 };
    int k, j;
    for (k = 0; k < ACC_N; k++) {
        const double the = c->pole_pairs * x.th, co = cos(the), si = sin(the);
        const double ed = -5.0 - x.id, eq = (k < ACC_N / 2 ? 15.0 : -10.0) - x.iq;
        const double ea = co * ed - si * eq, eb = si * ed + co * eq;
        double best = -1e300;
        int jb = 0;
        for (j = 1; j < 7; j++) {
            const double va = (2 * sa[j] - sb[j] - sc[j]) / 3.0, vb = (sb[j] - sc[j]) / SQRT3;
            if (va * ea + vb * eb > best) {
                best = va * ea + vb * eb;
                jb = j;
            }
        }
        if (ea * ea + eb * eb < 1.0) {
            jb = (k & 1) ? 7 : 0;
        }
        acc_seq[k] = (uint8_t)jb;
        ref_period(c, &x, sa[jb], sb[jb], sc[jb], 2.0, 4);
    }
}

static void run_seq(plant_t *p, double w0, double *id, double *iq, double *w, double *th)
{
    static const int sa[8] = { 0, 1, 1, 0, 0, 0, 1, 1 }, sb[8] = { 0, 0, 1, 1, 1, 0, 0, 1 },
                     sc[8] = { 0, 0, 0, 0, 1, 1, 1, 1 };
    fw_cmd_t c;
    int k;
    plant_set_mech(p, 0.0, w0, false);
    for (k = 0; k < ACC_N; k++) {
        const int j = acc_seq[k];
        plant_truth_t t;
        cmd_set(&c, sa[j], sb[j], sc[j], true, 2.0);
        plant_step(p, &c);
        plant_truth(p, &t);
        id[k] = t.i_d_a;
        iq[k] = t.i_q_a;
        w[k] = t.omega_m_rad_s;
        th[k] = t.theta_m_rad;
    }
}

static double angdiff(double a, double b)
{
    double d = fmod(a - b, TWO_PI);
    if (d > PI)
        d -= TWO_PI;
    if (d < -PI)
        d += TWO_PI;
    return fabs(d);
}

static void test_rk4_accuracy(void)
{
    static double rid[ACC_N], riq[ACC_N], rw[ACC_N], rth[ACC_N];
    static double id[ACC_N], iq[ACC_N], w[ACC_N], th[ACC_N];
    const int subs[4] = { 1, 2, 4, 1000 };
    const double speeds_rpm[2] = { 1000.0, 3000.0 };
    int si, k, n;
    for (si = 0; si < 2; si++) {
        const double w0 = speeds_rpm[si] * PI / 30.0;
        plant_cfg_t cfg;
        plant_t p;
        ref_x x = { 0.0, 0.0, w0, 0.0 };
        double emax[4] = { 0, 0, 0, 0 }, ewmax[4] = { 0, 0, 0, 0 }, ethmax[4] = { 0, 0, 0, 0 },
               eind = 0.0, imax = 0.0;
        static const int sa[8] = { 0, 1, 1, 0, 0, 0, 1, 1 }, sb[8] = { 0, 0, 1, 1, 1, 0, 0, 1 },
                         sc[8] = { 0, 0, 0, 0, 1, 1, 1, 1 };
        cfg_base(&cfg);
        cfg.b_visc_nms = 1e-3;
        make_sequence(&cfg, w0);
        cfg.substeps = 1000;
        plant_init(&p, &cfg);
        run_seq(&p, w0, rid, riq, rw, rth);
        /* the plant's 1000-substep run against the independent libm reference */
        for (k = 0; k < ACC_N; k++) {
            const int j = acc_seq[k];
            ref_period(&cfg, &x, sa[j], sb[j], sc[j], 2.0, 1000);
            eind = maxd(eind, maxd(fabs(x.id - rid[k]), fabs(x.iq - riq[k])));
            imax = maxd(imax, sqrt(rid[k] * rid[k] + riq[k] * riq[k]));
        }
        for (n = 0; n < 3; n++) {
            cfg.substeps = subs[n];
            plant_init(&p, &cfg);
            run_seq(&p, w0, id, iq, w, th);
            for (k = 0; k < ACC_N; k++) {
                emax[n] = maxd(emax[n], maxd(fabs(id[k] - rid[k]), fabs(iq[k] - riq[k])));
                ewmax[n] = maxd(ewmax[n], fabs(w[k] - rw[k]));
                ethmax[n] = maxd(ethmax[n], angdiff(th[k], rth[k]));
            }
        }
        printf("RK4 accuracy at %4.0f r/min over %d periods (FCS current loop, |i| up to %.1f A, "
               "speed %.0f..%.0f rad/s):\n",
               speeds_rpm[si], ACC_N, imax, w0, rw[ACC_N - 1]);
        for (n = 0; n < 3; n++) {
            printf("  substeps %d vs 1000: max |di| %.3e A, max |dw| %.3e rad/s, max |dtheta_m| "
                   "%.3e rad\n",
                   subs[n], emax[n], ewmax[n], ethmax[n]);
        }
        printf("  plant (1000 substeps) vs independent libm-rotation reference: max |di| %.3e A\n",
               eind);
        CHECK(eind < 1e-9, "plant with 1000 substeps equals the independent reference");
        CHECK(emax[0] < 1e-4, "1 RK4 substep: current error < 0.1 mA against 1000 substeps");
        CHECK(emax[1] < emax[0] / 12.0 && emax[2] < emax[1] / 12.0,
              "halving the step divides the error by ~16 (4th order)");
        CHECK(ewmax[0] < 1e-4 && ethmax[0] < 1e-6, "1 substep: speed and angle errors negligible");
    }
}

/* ------------------------------------------------------------------ inverter distortion */

static void test_distortion(void)
{
    plant_cfg_t cfg;
    plant_t p;
    double i, prev = 1e9, maxslope = 0.0, kdt;
    int k, mono = 1, odd = 1;

    CHECK_NEAR(plant_sigmoid(0.0), 0.0, 0.0, "sigmoid(0) = 0");
    CHECK_NEAR(plant_sigmoid(3.0), 1.0, 0.0, "sigmoid saturates at 3");
    CHECK_NEAR(plant_sigmoid(-7.0), -1.0, 0.0, "sigmoid saturates at -3");
    CHECK_NEAR((plant_sigmoid(3.0) - plant_sigmoid(3.0 - 1e-6)) / 1e-6, 0.0, 1e-5,
               "sigmoid is C1 at the knee");
    for (k = -4000; k <= 4000; k++) {
        const double x = k * 1e-3;
        CHECK(fabs(plant_sigmoid(x) - tanh(x)) < 0.025, "sigmoid within 0.025 of tanh");
        if (k > -4000 && plant_sigmoid(x) < plant_sigmoid(x - 1e-3))
            mono = 0;
        if (plant_sigmoid(-x) != -plant_sigmoid(x))
            odd = 0;
    }
    CHECK(mono, "sigmoid monotonic");
    CHECK(odd, "sigmoid odd");

    cfg_base(&cfg);
    cfg.dead_time_s = 2e-6;
    cfg.v_drop_v = 1.2;
    cfg.i_dt_a = 0.4;
    plant_init(&p, &cfg);
    kdt = 540.0 * 2e-6 / 50e-6; /* 21.6 V */
    /* carrier PWM (one rising and one falling edge per period): the classic -(v_dc t_d / Ts + v_drop) sgn i */
    CHECK_NEAR(plant_leg_distortion_v(&p, 10.0, 2), -(kdt + 1.2), 1e-12, "PWM distortion at +10 A");
    CHECK_NEAR(plant_leg_distortion_v(&p, -10.0, 2), kdt + 1.2, 1e-12, "PWM distortion at -10 A");
    CHECK_NEAR(plant_leg_distortion_v(&p, 0.0, 2), 0.0, 1e-15, "PWM distortion at 0 A");
    for (k = -3000; k <= 3000; k++) {
        const double v = plant_leg_distortion_v(&p, (i = k * 1e-3), 2);
        if (k > -3000) {
            if (v > prev)
                mono = 0;
            maxslope = maxd(maxslope, fabs(v - prev) / 1e-3);
        }
        CHECK(i * v <= 0.0, "distortion opposes the current");
        prev = v;
    }
    CHECK(mono, "distortion is monotonic in the current");
    CHECK(maxslope <= (kdt + 1.2) / 0.4 * 1.001,
          "distortion is smooth: slope bounded by (v_dc t_d/Ts + v_drop) / i_dt");
    /* FCS transitions: a rising edge loses volts only for i > 0, a falling edge gains volts only for i < 0 */
    CHECK_NEAR(plant_leg_distortion_v(&p, 10.0, 1), -(kdt + 1.2), 1e-12,
               "rising edge, i > 0: v_dc t_d / Ts lost");
    CHECK_NEAR(plant_leg_distortion_v(&p, -10.0, 1), 1.2, 1e-12,
               "rising edge, i < 0: no dead-time error");
    CHECK_NEAR(plant_leg_distortion_v(&p, 10.0, -1), -1.2, 1e-12,
               "falling edge, i > 0: no dead-time error");
    CHECK_NEAR(plant_leg_distortion_v(&p, -10.0, -1), kdt + 1.2, 1e-12,
               "falling edge, i < 0: v_dc t_d / Ts gained");
    CHECK_NEAR(plant_leg_distortion_v(&p, 10.0, 0), -1.2, 1e-12, "no edge: device drop only");
    CHECK_NEAR(plant_leg_distortion_v(&p, 0.3, 1) + plant_leg_distortion_v(&p, 0.3, -1),
               plant_leg_distortion_v(&p, 0.3, 2) - 1.2 * plant_sigmoid(0.3 / 0.4), 1e-12,
               "rise + fall = PWM period");

    /* in the loop: leg a toggles every period at standstill, b and c low: the mean a-terminal voltage
     * is v_dc / 2 - (v_dc t_d / Ts) sigma / 2, so i_d settles lower than without dead time */
    cfg.v_dc_v = 20.0;
    cfg.v_drop_v = 0.0;
    cfg.dead_time_s = 2.5e-6;
    cfg.i_dt_a = 0.5;
    plant_init(&p, &cfg);
    plant_set_mech(&p, 0.0, 0.0, true);
    {
        fw_cmd_t c;
        plant_truth_t t;
        double ud2 = 0.0, id2 = 0.0;
        for (k = 0; k < 12000; k++) {
            cmd_set(&c, k & 1, 0, 0, true, 0.0);
            plant_step(&p, &c);
            if (k >= 11000) {
                plant_truth(&p, &t);
                ud2 += t.u_d_v;
                id2 += t.i_d_a;
            }
        }
        CHECK_NEAR(ud2 / 1000, 2.0 / 3.0 * (10.0 - 0.5), 1e-3,
                   "toggling leg: mean u_d = 2/3 (v_dc/2 - k_dt/2)");
        CHECK_NEAR(id2 / 1000, 2.0 / 3.0 * (10.0 - 0.5) / 0.9, 2e-3,
                   "toggling leg: mean i_d follows");
    }
}

/* ------------------------------------------------------------------ PWM off */

int main(void)
{
    test_steady_state();
    test_energy();
    test_rk4_accuracy();
    test_distortion();
    return CHECK_DONE();
}
