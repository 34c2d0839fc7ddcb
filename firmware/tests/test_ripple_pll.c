/* Ripple/saliency PLL (ripple_err.h, est_ripple_pll.h): the phase detector's sign and magnitude
 * against a hand-computed case (and paper A's scalar form beside it), cross-saturation, and the
 * PLL closing the MPCC's loop on the plant: convergence from a wrong initial angle at standstill
 * and at speed, and tracking through zero speed and a reversal. */
#include <stdio.h>

#include "check.h"
#include "ripple_err.h"
#include "sensorless_loop.h"

/* Hand-computed (docs/sensorless.md): Gamma = diag(1/5 mH, 1/12 mH) = diag(200, 83.333) 1/H,
 * d = theta - theta^ = 0.1 rad, U = (100, 300) V in the estimated frame, Ts = 50 us.
 * R(d) Gamma R(d)^T - Gamma = [[-(a-b) s^2, (a-b) c s], [(a-b) c s, (a-b) s^2]]
 *   = [[-1.16278, 11.5890], [11.5890, 1.16278]]  (a-b = 116.667, s = sin 0.1, c = cos 0.1)
 * e = Ts (..) U = (0.168021, 0.0753867) A.
 * num_s = e_q U_d + e_d U_q = 57.9450; Ts D |U|^2 = 50e-6 * 58.3333 * 1e5 = 291.667;
 * 57.9450 / 291.667 = 0.198669 = sin 0.2.  num_c = e_d U_d - e_q U_q = -5.81390 -> -0.0199334
 * = cos 0.2 - 1.  Paper A's e_q U_d / (Ts D U_d^2) = 7.53867 / 29.1667 = 0.258469: biased. */
static void test_detector_hand_case(void)
{
    rerr_in_t in;
    rerr_out_t o;
    memset(&in, 0, sizeof in);
    in.g.g_dd = 200.0f;
    in.g.g_qq = 83.33333f;
    in.g.g_dq = 0.0f;
    in.g.g_qd = 0.0f;
    in.u_d_v = 100.0f;
    in.u_q_v = 300.0f;
    in.e_d_a = 0.168021f;
    in.e_q_a = 0.0753867f;
    rerr_eval(&in, 50e-6f, &o);
    CHECK_NEAR(o.norm, 50e-6 * 58.33333 * 58.33333 * 1e5, 0.01, "detector: norm = Ts D^2 |U|^2");
    CHECK_NEAR(o.sn / o.norm, sin(0.2), 2e-5, "detector: sn/norm = sin 2d (hand case)");
    CHECK_NEAR(o.cn / o.norm, cos(0.2) - 1.0, 2e-5, "detector: cn/norm = cos 2d - 1 (hand case)");
    CHECK(fabs(in.e_q_a * in.u_d_v / (50e-6 * 58.33333 * 1e4) - sin(0.2)) > 0.05,
          "detector: paper A's scalar e_q U_d alone is off by more than 0.05 here");
    /* the estimate leading the rotor (d < 0): the error turns negative */
    in.e_d_a = -in.e_d_a + 2.0f * 50e-6f * (-1.16278f * 100.0f);
    in.e_q_a = -in.e_q_a + 2.0f * 50e-6f * (1.16278f * 300.0f);
    rerr_eval(&in, 50e-6f, &o);
    CHECK_NEAR(o.sn / o.norm, -sin(0.2), 2e-5, "detector: d = -0.1 gives -sin 0.2");
}

/* Cross-saturation: Gamma with an off-diagonal term; e built from the rotation; the detector gives
 * sin 2d for any U and any d within the range (not the shifted equilibrium of a diagonal model). */
static void test_detector_cross_saturation(void)
{
    const double a = 230.0, b = 110.0, gdq = 18.0, ts = 50e-6;
    static const double dd[5] = { -0.6, -0.2, 0.0, 0.05, 0.5 };
    static const double uu[3][2] = { { 360.0, 0.0 }, { -120.0, 250.0 }, { 40.0, -330.0 } };
    int i, j;
    for (i = 0; i < 5; i++) {
        const double c = cos(dd[i]), s = sin(dd[i]);
        /* R G R^T with G = [[a, gdq], [gdq, b]] */
        const double r00 = c * c * a - 2.0 * c * s * gdq + s * s * b;
        const double r11 = s * s * a + 2.0 * c * s * gdq + c * c * b;
        const double r01 = c * s * (a - b) + (c * c - s * s) * gdq;
        for (j = 0; j < 3; j++) {
            rerr_in_t in;
            rerr_out_t o;
            in.g.g_dd = (float)a;
            in.g.g_qq = (float)b;
            in.g.g_dq = (float)gdq;
            in.g.g_qd = (float)gdq;
            in.u_d_v = (float)uu[j][0];
            in.u_q_v = (float)uu[j][1];
            in.e_d_a = (float)(ts * ((r00 - a) * uu[j][0] + (r01 - gdq) * uu[j][1]));
            in.e_q_a = (float)(ts * ((r01 - gdq) * uu[j][0] + (r11 - b) * uu[j][1]));
            rerr_eval(&in, (float)ts, &o);
            CHECK_NEAR(o.sn / o.norm, sin(2.0 * dd[i]), 2e-4, "detector: sin 2d with Gamma_dq");
            CHECK_NEAR(o.cn / o.norm, cos(2.0 * dd[i]) - 1.0, 2e-4,
                       "detector: cos 2d - 1 with Gamma_dq");
        }
    }
}

static void plant_cfg_rig(plant_cfg_t *pc)
{
    plant_cfg_default(pc);
    pc->i_noise_a = 0.02;
    pc->adc_lsb_a = 0.0244140625;
    pc->seed = 5u;
}

/* Closed current loop on the estimate at an imposed speed, from an initial error d0. */
static void run_converge(double rpm, double d0, float i_q_ref, const char *what)
{
    plant_cfg_t pc;
    rpll_cfg_t ec;
    sl_t s;
    int k;
    double sum2 = 0.0, sum = 0.0, worst = 0.0;
    char msg[160];
    const double w_m = rpm * 3.14159265358979 / 30.0, th0 = 1.0;
    plant_cfg_rig(&pc);
    sl_cfg_pll(&ec);
    sl_init(&s, &pc, &ec, th0, w_m, (float)(th0 - d0));
    s.i_q_ref_a = i_q_ref;
    for (k = 0; k < 4000; k++) { /* 0.2 s */
        sl_period(&s);
        if (k >= 2000) {
            const double e = sl_err(&s);
            sum2 += e * e;
            sum += e;
            worst = fabs(e) > worst ? fabs(e) : worst;
        }
    }
    snprintf(msg, sizeof msg, "pll %s: converges from %.2f rad (mean %.4f, rms %.4f, worst %.4f)",
             what, d0, sum / 2000.0, sqrt(sum2 / 2000.0), worst);
    printf("  %s\n", msg);
    CHECK(sqrt(sum2 / 2000.0) < 0.02 && worst < 0.06, msg);
    CHECK(s.eo.conf > 0.9f, "pll: confident once locked");
}

/* Through zero speed: a speed reversal -300 -> +300 r/min imposed over 0.4 s. */
static void test_reversal(void)
{
    plant_cfg_t pc;
    rpll_cfg_t ec;
    sl_t s;
    int k;
    double worst = 0.0, w_m = -300.0 * 3.14159265358979 / 30.0;
    const double acc = 2.0 * 300.0 * 3.14159265358979 / 30.0 / 0.4;
    char msg[120];
    plant_cfg_rig(&pc);
    sl_cfg_pll(&ec);
    sl_init(&s, &pc, &ec, 2.0, w_m, 2.0f);
    s.i_q_ref_a = 2.0f;
    for (k = 0; k < 2000; k++) {
        sl_period(&s);
    }
    for (k = 0; k < 8000; k++) {
        w_m += acc * 50e-6;
        plant_set_mech(&s.p, s.p.theta_m_rad, w_m, true);
        sl_period(&s);
        worst = fabs(sl_err(&s)) > worst ? fabs(sl_err(&s)) : worst;
    }
    snprintf(msg, sizeof msg, "pll: tracks a reversal through zero speed (worst %.4f rad)", worst);
    printf("  %s\n", msg);
    CHECK(worst < 0.05, msg);
    CHECK_NEAR(s.eo.omega_e_rad_s, 4.0 * w_m, 5.0, "pll: speed estimate after the reversal");
}

/* Paper A's nominal machine, no flux map, no input (u_valid false: the detector sees nothing). */
static void bare_cfg(rpll_cfg_t *c, rpll_in_t *in)
{
    memset(c, 0, sizeof *c);
    memset(in, 0, sizeof *in);
    c->ts_s = 50e-6f;
    c->pole_pairs = 4u;
    c->l_d_h = 5e-3f;
    c->l_q_h = 12e-3f;
    rerr_gamma_linear(&c->gamma, c->l_d_h, c->l_q_h);
}

/* The excitation: +-excite_a alternating every period, first +; none when excite_a is 0. */
static void test_excitation_alternates(void)
{
    rpll_cfg_t c;
    rpll_t e;
    rpll_in_t in;
    rpll_out_t o;
    int k, ok = 1;
    bare_cfg(&c, &in);
    c.excite_a = 1.5f;
    rpll_init(&e, &c);
    for (k = 0; k < 6; k++) {
        rpll_step(&e, &in, &o);
        ok = ok && o.i_d_hf_a == ((k & 1) == 0 ? 1.5f : -1.5f);
    }
    CHECK(ok, "pll: the excitation alternates +-excite_a every period");
    c.excite_a = 0.0f;
    rpll_init(&e, &c);
    rpll_step(&e, &in, &o);
    CHECK(o.i_d_hf_a == 0.0f, "pll: no excitation with excite_a 0");
}

/* The speed output: low-passed with tau = RPLL_SPEED_TAU_BW / bw, the observer's acceleration
 * times tau added, so a steady acceleration leaves no lag (a plain low-pass would lag tau a). */
static void test_speed_output_has_no_lag_on_a_ramp(void)
{
    rpll_cfg_t c;
    rpll_t e;
    rpll_in_t in;
    rpll_out_t o;
    int k;
    const float a = 2000.0f; /* rad/s^2, electrical */
    bare_cfg(&c, &in);
    c.bw_rad_s = 360.0f;
    rpll_init(&e, &c);
    rpll_reset(&e, 0.0f, 100.0f);
    e.acc = a; /* the observer's acceleration; no detector input (u_valid false): a pure ramp */
    for (k = 0; k < 4000; k++) {
        rpll_step(&e, &in, &o);
    }
    CHECK_NEAR(e.tau_w_s, RPLL_SPEED_TAU_BW / 360.0f, 1e-7, "pll: speed output's time constant");
    CHECK_NEAR(o.omega_e_rad_s, e.w, 0.01 * a * e.tau_w_s,
               "pll: the speed output follows a ramp without the low-pass's lag");
}

int main(void)
{
    test_excitation_alternates();
    test_speed_output_has_no_lag_on_a_ramp();
    test_detector_hand_case();
    test_detector_cross_saturation();
    run_converge(0.0, 0.6, 0.0f, "standstill, no current");
    run_converge(0.0, -0.6, 3.0f, "standstill, 3 A");
    run_converge(15.0, 0.5, 2.0f, "15 r/min");
    run_converge(240.0, -0.5, 5.0f, "240 r/min");
    run_converge(1000.0, 0.5, 5.0f, "1000 r/min");
    test_reversal();
    return CHECK_DONE();
}
