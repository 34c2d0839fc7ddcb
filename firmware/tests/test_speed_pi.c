/* Speed PI tests: gains, clamp, anti-windup, zero steady-state error under a constant load, the
 * ramp limiter, and the recommended defaults for paper A's drive in the full loop (MPCC + dq
 * plant + quantised encoder + observer + MTPA): 5 N m load steps at 15, 240 and 1000 r/min. */
#include <stdio.h>
#include <math.h>
#include "check.h"
#include "speed_pi.h"
#include "ramp.h"
#include "mpcc.h"
#include "mtpa.h"
#include "enc_angle.h"

#define PI_D          3.14159265358979323846
#define RPM_PER_RAD_S (60.0 / (2.0 * PI_D))

/* Paper A's motor. */
#define R_OHM      0.9
#define LD_H       0.005
#define LQ_H       0.012
#define PSI_WB     0.18
#define POLES      4
#define J_KGM2     0.0036
#define VDC_V      540.0
#define TS_S       50e-6
#define SPEED_DIV  20 /* 1 kHz speed loop */
#define I_MAX_A    15.0f
#define ENC_COUNTS 10000u /* 2500 lines x 4 */

/* The recommended defaults (docs/control.md). */
#define BW_SPEED_RAD_S 100.0f
#define BW_OBS_RAD_S   1000.0f
#define REF_WEIGHT     0.7f

static float kt_nominal(void)
{
    return 1.5f * (float)POLES * (float)PSI_WB;
}

/* ------------------------------------------------------------------ unit tests */
static void test_basic(void)
{
    speed_pi_cfg_t c = { 0.5f, 10.0f, 1e-3f, 15.0f };
    speed_pi_t p;
    float u;
    speed_pi_init(&p, &c);
    u = speed_pi_step(&p, 2.0f, 0.0f);
    CHECK_NEAR(u, 0.5f * 2.0f + 10.0f * 1e-3f * 2.0f, 1e-6, "P + I on the first step");
    u = speed_pi_step(&p, 2.0f, 0.0f);
    CHECK_NEAR(u, 1.0f + 2.0f * 0.02f, 1e-6, "integrator accumulates");
    u = speed_pi_step(&p, 1000.0f, 0.0f);
    CHECK_NEAR(u, 15.0f, 1e-6, "clamped to +out_max");
    CHECK(p.saturated, "saturation flag");
    u = speed_pi_step(&p, -1000.0f, 0.0f);
    CHECK_NEAR(u, -15.0f, 1e-6, "clamped to -out_max");
    speed_pi_reset(&p, 3.0f);
    u = speed_pi_step(&p, 0.0f, 0.0f);
    CHECK_NEAR(u, 3.0f, 1e-6, "reset preloads the integrator (bumpless)");
    speed_pi_reset(&p, 100.0f);
    CHECK_NEAR(p.integ_a, 15.0f, 1e-6, "preload clamped");
    speed_pi_set_ref_weight(&p, 0.7f);
    speed_pi_preset(&p, 2.0f, 100.0f, 100.0f);
    u = speed_pi_step(&p, 100.0f, 100.0f);
    CHECK_NEAR(u, 2.0f, 1e-4, "preset is bumpless with b < 1");
    speed_pi_set_ref_weight(&p, 1.0f);
    speed_pi_set_limit(&p, 5.0f);
    CHECK_NEAR(p.integ_a, 5.0f, 1e-6, "new limit clamps the integrator");
    u = speed_pi_step(&p, 0.0f, 0.0f);
    CHECK_NEAR(u, 5.0f, 1e-6, "new limit clamps the output");
}

static void test_design(void)
{
    float kp, ki;
    speed_pi_design((float)J_KGM2, kt_nominal(), BW_SPEED_RAD_S, &kp, &ki);
    CHECK_NEAR(kp, J_KGM2 * 100.0 / 1.08, 1e-5, "kp = J bw / kt");
    CHECK_NEAR(ki, kp * 25.0f, 1e-4, "ki = kp bw / 4");
    printf("  paper A, bw 100 rad/s: kp %.4f A s/rad, ki %.3f A/rad\n", kp, ki);
    speed_pi_design(0.0f, 1.0f, 100.0f, &kp, &ki);
    CHECK(kp == 0.0f && ki == 0.0f, "invalid inputs give zero gains");
}

/* Ideal-current plant: J dw/dt = kt i - T_L, the command acts one speed period later. */
typedef struct {
    double over_max, err_end;
    int sat_toggles;
} step_t;

static step_t run_inertia(float kp, float ki, float b, bool anti_windup, double w_ref,
                          double t_load_nm, double t_end)
{
    speed_pi_cfg_t c = { kp, ki, 1e-3f, I_MAX_A };
    speed_pi_t p;
    step_t r = { 0.0, 0.0, 0 };
    double w = 0.0, i_cmd = 0.0, integ = 0.0;
    long k, n = (long)(t_end / 1e-3 + 0.5);
    bool sat_prev = false;
    const double kt = kt_nominal();
    speed_pi_init(&p, &c);
    speed_pi_set_ref_weight(&p, b);
    for (k = 0; k < n; k++) {
        double u;
        int s;
        if (anti_windup) {
            u = speed_pi_step(&p, (float)w_ref, (float)w);
        } else { /* naive PI with an output clamp only */
            const double e = w_ref - w;
            integ += ki * 1e-3 * e;
            u = kp * e + integ;
            u = u > I_MAX_A ? I_MAX_A : (u < -I_MAX_A ? -I_MAX_A : u);
        }
        /* integrate over one speed period with the previous command (delay) */
        for (s = 0; s < 20; s++) {
            w += 50e-6 * (kt * i_cmd - t_load_nm) / J_KGM2;
        }
        i_cmd = u;
        if (w - w_ref > r.over_max) {
            r.over_max = w - w_ref;
        }
        if (anti_windup && p.saturated != sat_prev) {
            r.sat_toggles++;
            sat_prev = p.saturated;
        }
    }
    r.err_end = w_ref - w;
    return r;
}

static void test_anti_windup(void)
{
    float kp, ki;
    const double w_ref = 1000.0 / RPM_PER_RAD_S;
    step_t a, b, c;
    speed_pi_design((float)J_KGM2, kt_nominal(), BW_SPEED_RAD_S, &kp, &ki);
    a = run_inertia(kp, ki, 1.0f, true, w_ref, 0.0, 1.0);
    b = run_inertia(kp, ki, 1.0f, false, w_ref, 0.0, 1.0);
    c = run_inertia(kp, ki, 0.7f, true, w_ref, 0.0, 1.0);
    printf("  0 -> 1000 r/min step at 15 A: overshoot %.1f r/min with anti-windup (b = 0.7: %.1f),"
           " %.1f with a clamped naive PI; %d saturation toggles\n",
           a.over_max * RPM_PER_RAD_S, c.over_max * RPM_PER_RAD_S, b.over_max * RPM_PER_RAD_S,
           a.sat_toggles);
    CHECK(a.over_max < 0.08 * w_ref, "anti-windup: overshoot below 8 % after a saturated step");
    CHECK(a.over_max < 0.3 * b.over_max, "anti-windup beats a clamped naive PI");
    CHECK(c.over_max < 0.01 * w_ref, "set-point weight 0.7: overshoot below 1 %");
    CHECK(a.sat_toggles <= 2, "one saturation interval, no chatter");
    CHECK(fabs(a.err_end) < 1e-3 && fabs(c.err_end) < 1e-3, "settles");
}

static void test_disturbance(void)
{
    float kp, ki;
    const double w_ref = 240.0 / RPM_PER_RAD_S;
    step_t a;
    speed_pi_design((float)J_KGM2, kt_nominal(), BW_SPEED_RAD_S, &kp, &ki);
    a = run_inertia(kp, ki, 1.0f, true, w_ref, 3.0, 2.0);
    CHECK(fabs(a.err_end) < 1e-4, "zero steady-state error with a constant load torque");
    a = run_inertia(kp, ki, 0.7f, true, w_ref, 3.0, 2.0);
    CHECK(fabs(a.err_end) < 1e-4, "zero steady-state error with a constant load torque (b = 0.7)");
    a = run_inertia(kp, ki, 0.7f, true, 1500.0 / RPM_PER_RAD_S, 0.0, 2.0);
    CHECK(fabs(a.err_end) < 1e-4,
          "b = 0.7 reaches a high reference (integrator not cut by the clamp)");
    /* and with a load beyond the current limit the speed falls, the state stays bounded */
    a = run_inertia(kp, ki, 1.0f, true, w_ref, 30.0, 0.5);
    CHECK(a.err_end > 0.0, "overload: speed falls");
}

static void test_nan(void)
{
    speed_pi_cfg_t c = { 0.5f, 10.0f, 1e-3f, 15.0f };
    speed_pi_t p;
    float u;
    speed_pi_init(&p, &c);
    u = speed_pi_step(&p, 2.0f, 0.0f);
    u = speed_pi_step(&p, NAN, 0.0f);
    CHECK(u == u && p.integ_a == p.integ_a, "NaN input: output and state stay numbers");
}

static void test_ramp(void)
{
    ramp_cfg_t c = { 1000.0f, 1e-3f };
    ramp_t r;
    int k;
    float y = 0.0f;
    ramp_init(&r, &c);
    for (k = 0; k < 100; k++) {
        y = ramp_step(&r, 500.0f);
    }
    CHECK_NEAR(y, 100.0f, 1e-3, "1000 rpm/s for 0.1 s: 100 rpm");
    for (k = 0; k < 1000; k++) {
        y = ramp_step(&r, 500.0f);
    }
    CHECK_NEAR(y, 500.0f, 1e-6, "reaches the target exactly, no overshoot");
    for (k = 0; k < 100; k++) {
        y = ramp_step(&r, -500.0f);
    }
    CHECK_NEAR(y, 400.0f, 1e-3, "ramps down at the same rate");
    ramp_set_rate(&r, 0.0f);
    y = ramp_step(&r, -500.0f);
    CHECK_NEAR(y, -500.0f, 1e-6, "rate 0 = step");
    ramp_reset(&r, 42.0f);
    CHECK_NEAR(r.out_rpm, 42.0f, 1e-6, "reset");
}

/* ------------------------------------------------------------------ full loop */
typedef struct {
    double i_d, i_q, th_m, w_m;
} drive_t;

#define N_SUB 20

static void drive_period(drive_t *p, int sw, double t_load)
{
    const double h = TS_S / N_SUB;
    const double ua = VDC_V * (2.0 * (sw & 1) - ((sw >> 1) & 1) - ((sw >> 2) & 1)) / 3.0;
    const double ub = VDC_V * (((sw >> 1) & 1) - ((sw >> 2) & 1)) / sqrt(3.0);
    int n;
    for (n = 0; n < N_SUB; n++) {
        const double th = POLES * p->th_m, c = cos(th), s = sin(th), we = POLES * p->w_m;
        const double ud = c * ua + s * ub, uq = -s * ua + c * ub;
        const double did = (ud - R_OHM * p->i_d + we * LQ_H * p->i_q) / LD_H;
        const double diq = (uq - R_OHM * p->i_q - we * LD_H * p->i_d - we * PSI_WB) / LQ_H;
        const double te = 1.5 * POLES * (PSI_WB * p->i_q + (LD_H - LQ_H) * p->i_d * p->i_q);
        p->i_d += h * did;
        p->i_q += h * diq;
        p->w_m += h * (te - t_load) / J_KGM2;
        p->th_m += h * p->w_m;
    }
}

static uint32_t enc_count_of(double th_m)
{
    double f = fmod(th_m, 2.0 * PI_D);
    if (f < 0.0) {
        f += 2.0 * PI_D;
    }
    return (uint32_t)floor(f / (2.0 * PI_D) * ENC_COUNTS) % ENC_COUNTS;
}

typedef struct {
    double t_rec_on, t_rec_off; /* recovery times after load on / off */
    double dip_rpm, rise_rpm;   /* worst deviation after load on / off */
    double i_s_peak;
    int sat_periods, sat_toggles;
    double speed_std_rpm; /* true speed ripple before the load step */
    double over_rpm;      /* overshoot after the reference step */
} loop_t;

/* seg: speed targets (rpm) with their start times, load on [t_on, t_off) */
static loop_t run_loop(double rpm0, double rpm1, double t_step, double t_on, double t_off,
                       double load_nm, double t_end, uint16_t cur_mode)
{
    mpcc_cfg_t mc;
    mpcc_t m;
    speed_pi_cfg_t sc;
    speed_pi_t sp;
    enc_cfg_t ec;
    enc_t e;
    fw_motor_t mot = { POLES,         (float)R_OHM,  (float)LD_H, (float)LQ_H,
                       (float)PSI_WB, (float)J_KGM2, I_MAX_A,     1500.0f };
    drive_t p = { 0.0, 0.0, 0.1, 0.0 };
    fw_dq_t ref = { 0.0f, 0.0f };
    loop_t r = { 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0, 0.0 };
    long k, n_k = (long)(t_end / TS_S + 0.5);
    int pending = 0, n_std = 0;
    bool sat_prev = false;
    double last_out_on = t_on, last_out_off = t_off, s1 = 0.0, s2 = 0.0;
    static double hist[200];
    double hist_sum = 0.0;
    float kp, ki;

    mpcc_cfg_default(&mc);
    mc.ts_s = (float)TS_S;
    mpcc_init(&m, &mc);
    speed_pi_design((float)J_KGM2, kt_nominal(), BW_SPEED_RAD_S, &kp, &ki);
    sc.kp_a_per_rad_s = kp;
    sc.ki_a_per_rad = ki;
    sc.ts_s = (float)(TS_S * SPEED_DIV);
    sc.out_max_a = I_MAX_A;
    speed_pi_init(&sp, &sc);
    speed_pi_set_ref_weight(&sp, REF_WEIGHT);
    ec.counts = ENC_COUNTS;
    ec.pole_pairs = POLES;
    ec.offset_e_rad = 0.0f;
    ec.bw_rad_s = BW_OBS_RAD_S;
    ec.ts_s = (float)TS_S;
    enc_init(&e, &ec);
    /* start at rpm0 in steady state */
    p.w_m = rpm0 / RPM_PER_RAD_S;
    speed_pi_preset(&sp, 0.0f, (float)p.w_m, (float)p.w_m);
    enc_reset(&e, enc_count_of(p.th_m));
    e.w_cps = (float)(p.w_m / (2.0 * PI_D) * ENC_COUNTS);

    for (k = 0; k < n_k; k++) {
        const double t = k * TS_S;
        const double rpm_ref = t < t_step ? rpm0 : rpm1;
        const double tl = (t >= t_on && t < t_off) ? load_nm : 0.0;
        double rpm_true; /* 10 ms moving average of the true speed (what a scope trace shows) */
        const double band = fmax(0.02 * fabs(rpm_ref), 2.0);
        enc_out_t eo;
        mpcc_in_t in;
        mpcc_out_t mo;
        enc_step(&e, enc_count_of(p.th_m), &eo);
        if (k % SPEED_DIV == 0) {
            const float is = speed_pi_step(&sp, (float)(rpm_ref / RPM_PER_RAD_S), eo.omega_m_rad_s);
            mtpa_split(&mot, cur_mode, is, &ref);
            if (fabs(is) > r.i_s_peak) {
                r.i_s_peak = fabs(is);
            }
            if (sp.saturated) {
                r.sat_periods++;
            }
            if (sp.saturated != sat_prev) {
                r.sat_toggles++;
                sat_prev = sp.saturated;
            }
        }
        /* measured currents in the encoder's frame */
        {
            const double dth = eo.theta_e_rad - POLES * p.th_m;
            in.i_d_a = (float)(cos(dth) * p.i_d + sin(dth) * p.i_q);
            in.i_q_a = (float)(-sin(dth) * p.i_d + cos(dth) * p.i_q);
        }
        in.i_d_ref_a = ref.d;
        in.i_q_ref_a = ref.q;
        in.theta_e_rad = eo.theta_e_rad;
        in.omega_e_rad_s = eo.omega_e_rad_s;
        in.v_dc_v = (float)VDC_V;
        in.r_s_ohm = (float)R_OHM;
        in.l_d_h = (float)LD_H;
        in.l_q_h = (float)LQ_H;
        in.psi_f_wb = (float)PSI_WB;
        mpcc_step(&m, &in, &mo);
        drive_period(&p, pending, tl);
        pending = mo.s_abc_next;
        if (k >= 200) {
            hist_sum -= hist[k % 200];
        }
        hist[k % 200] = p.w_m * RPM_PER_RAD_S;
        hist_sum += hist[k % 200];
        rpm_true = k >= 199 ? hist_sum / 200.0 : p.w_m * RPM_PER_RAD_S;

        if (t > t_on - 0.1 && t < t_on) {
            s1 += rpm_true - rpm_ref;
            s2 += (rpm_true - rpm_ref) * (rpm_true - rpm_ref);
            n_std++;
        }
        if (t >= t_step && rpm_true - rpm_ref > r.over_rpm) {
            r.over_rpm = rpm_true - rpm_ref;
        }
        if (t >= t_on && t < t_off) {
            if (rpm_ref - rpm_true > r.dip_rpm) {
                r.dip_rpm = rpm_ref - rpm_true;
            }
            if (fabs(rpm_true - rpm_ref) > band) {
                last_out_on = t;
            }
        }
        if (t >= t_off) {
            if (rpm_true - rpm_ref > r.rise_rpm) {
                r.rise_rpm = rpm_true - rpm_ref;
            }
            if (fabs(rpm_true - rpm_ref) > band) {
                last_out_off = t;
            }
        }
    }
    r.t_rec_on = last_out_on - t_on;
    r.t_rec_off = last_out_off - t_off;
    if (n_std > 0) {
        r.speed_std_rpm = sqrt(fmax(s2 / n_std - (s1 / n_std) * (s1 / n_std), 0.0));
    }
    return r;
}

static void test_load_steps(void)
{
    static const double rpm[3] = { 15.0, 240.0, 1000.0 };
    int n;
    for (n = 0; n < 3; n++) {
        loop_t r = run_loop(rpm[n], rpm[n], 0.0, 0.3, 0.9, 5.0, 1.5, MTPA_MODE_MTPA);
        printf(
            "  %5.0f r/min, 5 N m step: dip %.1f r/min, recovered (+-max(2 %%, 2 r/min)) in %.3f s;"
            " release: +%.1f r/min, %.3f s; i_s peak %.2f A, saturated %d ms; speed ripple %.2f "
            "r/min rms\n",
            rpm[n], r.dip_rpm, r.t_rec_on, r.rise_rpm, r.t_rec_off, r.i_s_peak, r.sat_periods,
            r.speed_std_rpm);
        CHECK(r.t_rec_on < 0.3, "load step recovered within 0.3 s");
        CHECK(r.t_rec_off < 0.3, "load release recovered within 0.3 s");
        CHECK(r.sat_periods == 0 && r.i_s_peak < 0.8 * I_MAX_A,
              "no current limit during a 5 N m step");
        CHECK(r.speed_std_rpm < fmax(0.01 * rpm[n], 1.0),
              "steady speed ripple below max(1 %, 1 r/min) rms");
    }
    {
        loop_t r = run_loop(240.0, 240.0, 0.0, 0.3, 0.9, 5.0, 1.5, MTPA_MODE_ID_ZERO);
        printf("  240 r/min with i_d = 0: recovered in %.3f s, i_s peak %.2f A\n", r.t_rec_on,
               r.i_s_peak);
        CHECK(r.t_rec_on < 0.3, "i_d = 0 mode: recovered within 0.3 s");
    }
}

/* Paper A Fig. 17: 50 -> 500 -> 1000 r/min steps (no ramp): one clean saturation interval each. */
static void test_speed_steps(void)
{
    loop_t a = run_loop(50.0, 500.0, 0.1, 10.0, 10.0, 0.0, 0.6, MTPA_MODE_MTPA);
    loop_t b = run_loop(500.0, 1000.0, 0.1, 10.0, 10.0, 0.0, 0.6, MTPA_MODE_MTPA);
    printf(
        "  50 -> 500 r/min: saturated %d ms, %d toggles, overshoot %.1f r/min; 500 -> 1000: %d ms,"
        " %d toggles, overshoot %.1f r/min\n",
        a.sat_periods, a.sat_toggles, a.over_rpm, b.sat_periods, b.sat_toggles, b.over_rpm);
    CHECK(a.sat_toggles <= 2 && b.sat_toggles <= 2, "no current-limit chatter on speed steps");
    CHECK(a.over_rpm < 0.05 * 450.0 && b.over_rpm < 0.05 * 500.0,
          "overshoot below 5 % of the step");
}

int main(void)
{
    test_basic();
    test_design();
    test_anti_windup();
    test_disturbance();
    test_nan();
    test_ramp();
    test_load_steps();
    test_speed_steps();
    return CHECK_DONE();
}
