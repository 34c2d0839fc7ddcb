/* Encoder angle and speed observer tests: angle mapping and wrap across the count rollover (both
 * directions), speed accuracy and noise with a quantised 10000-count encoder at 15 and 1000 r/min,
 * tracking of a speed step and of a load-step dip, long-run precision. */
#include <stdio.h>
#include <math.h>
#include "check.h"
#include "enc_angle.h"
#include "transforms.h"

#define PI_D          3.14159265358979323846
#define TS_S          50e-6
#define N_CNT         10000u
#define RPM_PER_RAD_S (60.0 / (2.0 * PI_D))

static enc_cfg_t cfg_paper(void)
{
    enc_cfg_t c;
    c.counts = N_CNT;
    c.pole_pairs = 4u;
    c.offset_e_rad = 0.0f;
    c.bw_rad_s = ENC_BW_DEFAULT_RAD_S;
    c.ts_s = (float)TS_S;
    return c;
}

/* Quantised reading of a true mechanical angle (floor, as an incremental counter does). */
static uint32_t count_of(double th_m)
{
    double f = fmod(th_m, 2.0 * PI_D);
    if (f < 0.0) {
        f += 2.0 * PI_D;
    }
    return (uint32_t)floor(f / (2.0 * PI_D) * N_CNT) % N_CNT;
}

static double ang_diff(double a, double b)
{
    double d = fmod(a - b, 2.0 * PI_D);
    if (d > PI_D) {
        d -= 2.0 * PI_D;
    } else if (d <= -PI_D) {
        d += 2.0 * PI_D;
    }
    return d;
}

static void test_angle_map(void)
{
    enc_cfg_t c = cfg_paper();
    enc_t e;
    enc_out_t o;
    static const uint32_t cnt[6] = { 0u, 1u, 2500u, 1234u, 9999u, 10000u + 17u };
    int n;
    c.offset_e_rad = 0.5f;
    enc_init(&e, &c);
    for (n = 0; n < 6; n++) {
        const double thm = 2.0 * PI_D * (double)(cnt[n] % N_CNT) / N_CNT;
        double the = fmod(4.0 * thm + 0.5, 2.0 * PI_D);
        enc_reset(&e, cnt[n]);
        enc_step(&e, cnt[n], &o);
        CHECK_NEAR(o.theta_m_rad, thm, 2e-6, "theta_m = count 2pi/counts");
        CHECK(fabs(ang_diff(o.theta_e_rad, the)) < 2e-6, "theta_e = wrap(p theta_m + offset)");
        CHECK(o.theta_e_rad >= 0.0f && o.theta_e_rad < FW_TWO_PI_F, "theta_e in [0, 2pi)");
    }
    /* count 2500 with p = 4 is a whole electrical turn: theta_e = offset */
    enc_reset(&e, 2500u);
    enc_step(&e, 2500u, &o);
    CHECK_NEAR(o.theta_e_rad, 0.5f, 1e-6, "quarter mechanical turn = 4 electrical turns");
    CHECK_NEAR(o.theta_e_obs_rad, 0.5f, 1e-5, "observer angle at rest = raw angle");

    /* transforms' wraps */
    CHECK_NEAR(tf_wrap_2pi(-0.1f), FW_TWO_PI_F - 0.1f, 1e-6, "wrap_2pi of a negative angle");
    CHECK_NEAR(tf_wrap_2pi(7.0f), 7.0f - FW_TWO_PI_F, 1e-6, "wrap_2pi above 2pi");
    CHECK(tf_wrap_2pi(FW_TWO_PI_F) < FW_TWO_PI_F, "wrap_2pi(2pi) < 2pi");
    CHECK_NEAR(tf_wrap_pi(FW_PI_F + 0.1f), -FW_PI_F + 0.1f, 1e-6, "wrap_pi above pi");
    CHECK_NEAR(tf_wrap_pi(-FW_PI_F), FW_PI_F, 1e-6, "wrap_pi(-pi) = pi");
    CHECK_NEAR(tf_wrap_pi(-1.0f), -1.0f, 1e-6, "wrap_pi keeps (-pi, pi]");
    CHECK_NEAR(tf_wrap_2pi(-100.0f * FW_TWO_PI_F - 0.25f), FW_TWO_PI_F - 0.25f, 1e-3,
               "wrap_2pi many turns");
}

/* Constant speed through the rollover in both directions: no speed glitch, continuous angles. */
static void test_rollover(void)
{
    static const double rpm[2] = { 600.0, -600.0 };
    int n;
    for (n = 0; n < 2; n++) {
        enc_cfg_t c = cfg_paper();
        enc_t e;
        enc_out_t o;
        const double w = rpm[n] / RPM_PER_RAD_S;
        double th = rpm[n] > 0.0 ? 2.0 * PI_D - 0.3 : 0.3, max_spd = 0.0, max_jump = 0.0,
               max_obs = 0.0;
        double prev_obs = -1.0;
        long k;
        int crossed = 0;
        uint32_t prev_cnt = count_of(th);
        enc_init(&e, &c);
        enc_reset(&e, count_of(th));
        e.w_cps = (float)(w / (2.0 * PI_D) * N_CNT);
        for (k = 0; k < 20000; k++) { /* 1 s: 10 mechanical turns */
            const uint32_t cnt = count_of(th);
            enc_step(&e, cnt, &o);
            if ((rpm[n] > 0.0 && cnt < prev_cnt) || (rpm[n] < 0.0 && cnt > prev_cnt)) {
                crossed++;
            }
            prev_cnt = cnt;
            if (k > 200) {
                if (fabs(o.speed_rpm - rpm[n]) > max_spd) {
                    max_spd = fabs(o.speed_rpm - rpm[n]);
                }
                if (fabs(ang_diff(o.theta_e_obs_rad, fmod(4.0 * th, 2.0 * PI_D))) > max_obs) {
                    max_obs = fabs(ang_diff(o.theta_e_obs_rad, fmod(4.0 * th, 2.0 * PI_D)));
                }
                if (prev_obs >= 0.0 && fabs(ang_diff(o.theta_e_obs_rad, prev_obs)) > max_jump) {
                    max_jump = fabs(ang_diff(o.theta_e_obs_rad, prev_obs));
                }
            }
            prev_obs = o.theta_e_obs_rad;
            th += w * TS_S;
        }
        printf(
            "  %+5.0f r/min through %d rollovers: max speed error %.3f r/min, observer angle error"
            " %.4f rad el., max step %.4f rad\n",
            rpm[n], crossed, max_spd, max_obs, max_jump);
        CHECK(crossed >= 9, "the count rolled over");
        CHECK(max_spd < 0.5, "no speed glitch at the rollover");
        CHECK(max_obs < 4.0 * 2.0 * PI_D / N_CNT * 1.5,
              "observer angle within 1.5 counts (electrical)");
        CHECK(max_jump < 4.0 * fabs(w) * TS_S * 1.5 + 0.01, "observer angle continuous");
    }
}

typedef struct {
    double mean, std, max;
} stat_t;

static stat_t speed_stats(double rpm, float bw)
{
    enc_cfg_t c = cfg_paper();
    enc_t e;
    enc_out_t o;
    const double w = rpm / RPM_PER_RAD_S;
    double th = 0.123, s = 0.0, s2 = 0.0;
    stat_t r = { 0.0, 0.0, 0.0 };
    long k, n = 0;
    c.bw_rad_s = bw;
    enc_init(&e, &c);
    enc_reset(&e, count_of(th));   /* from rest: the observer must pull in */
    for (k = 0; k < 100000; k++) { /* 5 s */
        enc_step(&e, count_of(th), &o);
        th += w * TS_S;
        if (k >= 20000) { /* after 1 s */
            const double d = o.speed_rpm - rpm;
            s += d;
            s2 += d * d;
            n++;
            if (fabs(d) > r.max) {
                r.max = fabs(d);
            }
        }
    }
    CHECK_NEAR(o.omega_e_rad_s, 4.0f * o.omega_m_rad_s, 1e-3, "omega_e = p omega_m");
    CHECK_NEAR(o.speed_rpm, o.omega_m_rad_s * RPM_PER_RAD_S, 1e-3, "speed_rpm = omega_m 60/2pi");
    r.mean = s / n;
    r.std = sqrt(fmax(s2 / n - r.mean * r.mean, 0.0));
    return r;
}

static void test_speed_accuracy(void)
{
    static const double rpm[5] = { 15.0, 15.37, -15.0, 240.0, 1000.0 };
    int n;
    for (n = 0; n < 5; n++) {
        const stat_t a = speed_stats(rpm[n], ENC_BW_DEFAULT_RAD_S);
        printf("  %7.2f r/min, bw %.0f rad/s: mean error %+.4f r/min, std %.4f, max %.4f r/min\n",
               rpm[n], (double)ENC_BW_DEFAULT_RAD_S, a.mean, a.std, a.max);
        CHECK(fabs(a.mean) < 0.01 * fabs(rpm[n]) * 0.1 + 0.01,
              "mean speed error < 0.1 % + 0.01 r/min");
        CHECK(a.std < 0.2 && a.max < 0.5, "low-noise speed (std < 0.2 r/min, max < 0.5 r/min)");
    }
    {
        const stat_t lo = speed_stats(15.37, 314.0f), hi = speed_stats(15.37, 3000.0f);
        printf("  15.37 r/min: std %.4f r/min at bw 314, %.4f at 3000 rad/s\n", lo.std, hi.std);
        CHECK(lo.std < hi.std, "noise grows with the observer bandwidth");
    }
}

/* Speed step 0 -> 240 r/min (an ideal, infinitely stiff step in the true speed). */
static void test_speed_step(void)
{
    enc_cfg_t c = cfg_paper();
    enc_t e;
    enc_out_t o;
    const double w1 = 240.0 / RPM_PER_RAD_S;
    double th = 1.0, over = 0.0, t_settle = -1.0;
    long k;
    enc_init(&e, &c);
    enc_reset(&e, count_of(th));
    for (k = 0; k < 4000; k++) { /* 0.2 s */
        const double w = k >= 200 ? w1 : 0.0;
        enc_step(&e, count_of(th), &o);
        th += w * TS_S;
        if (k >= 200) {
            if (o.speed_rpm - 240.0 > over) {
                over = o.speed_rpm - 240.0;
            }
            if (fabs(o.speed_rpm - 240.0) > 2.4) {
                t_settle = (k - 200) * TS_S;
            }
        }
    }
    printf("  0 -> 240 r/min step: overshoot %.1f %%, within 1 %% after %.2f ms\n",
           over / 240.0 * 100.0, t_settle * 1e3);
    CHECK(over < 0.08 * 240.0, "step overshoot below 8 % (zeta = 0.707)");
    CHECK(t_settle < 0.010, "settles to 1 % within 10 ms");
}

/* A load-step dip like the speed loop's: w(t) = w0 - A t exp(-t/tau) (paper A drive at 15 r/min:
 * ~100 r/min dip, reversing). The observer must follow it: the minimum matches within 5 %. */
static void test_dip(void)
{
    enc_cfg_t c = cfg_paper();
    enc_t e;
    enc_out_t o;
    const double w0 = 15.0 / RPM_PER_RAD_S, tau = 0.02;
    const double a_dip = 5.0 / 0.0036; /* initial deceleration: 5 N m on J = 0.0036 */
    double th = 0.2, min_true = 1e9, min_est = 1e9, max_err = 0.0;
    long k;
    enc_init(&e, &c);
    enc_reset(&e, count_of(th));
    e.w_cps = (float)(w0 / (2.0 * PI_D) * N_CNT);
    for (k = 0; k < 6000; k++) {
        const double t = k * TS_S;
        const double w = w0 - a_dip * t * exp(-t / tau);
        enc_step(&e, count_of(th), &o);
        th += w * TS_S;
        if (w * RPM_PER_RAD_S < min_true) {
            min_true = w * RPM_PER_RAD_S;
        }
        if (o.speed_rpm < min_est) {
            min_est = o.speed_rpm;
        }
        if (fabs(o.speed_rpm - w * RPM_PER_RAD_S) > max_err) {
            max_err = fabs(o.speed_rpm - w * RPM_PER_RAD_S);
        }
    }
    printf(
        "  load-step dip: true minimum %.1f r/min, observed %.1f r/min, max lag error %.1f r/min\n",
        min_true, min_est, max_err);
    CHECK(fabs(min_est - min_true) < 0.05 * fabs(min_true - 15.0),
          "dip minimum followed within 5 %");
    CHECK(max_err < 25.0, "lag error during the dip below 25 r/min");
}

/* Hours of rotation: the observer angle stays within a count (integer + fraction state). */
static void test_long_run(void)
{
    enc_cfg_t c = cfg_paper();
    enc_t e;
    enc_out_t o;
    const double w = 1000.0 / RPM_PER_RAD_S;
    double cnt_true = 0.0, max_err = 0.0;
    long k;
    enc_init(&e, &c);
    enc_reset(&e, 0u);
    e.w_cps = (float)(w / (2.0 * PI_D) * N_CNT);
    for (k = 0; k < 2000000; k++) { /* 100 s, 1667 turns */
        const uint32_t cnt = (uint32_t)fmod(floor(cnt_true), (double)N_CNT);
        enc_step(&e, cnt, &o);
        cnt_true += w / (2.0 * PI_D) * N_CNT * TS_S;
        if (k > 1990000 && fabs(o.err_counts) > max_err) {
            max_err = fabs(o.err_counts);
        }
    }
    printf("  after 100 s at 1000 r/min: innovation within %.3f counts, speed %.3f r/min\n",
           max_err, o.speed_rpm);
    CHECK(max_err < 1.5, "no drift over long runs");
    CHECK_NEAR(o.speed_rpm, 1000.0f, 0.2, "speed after a long run");
}

static void test_guards(void)
{
    enc_cfg_t c = cfg_paper();
    enc_t e;
    enc_out_t o;
    c.counts = 0u;
    c.bw_rad_s = 0.0f;
    enc_init(&e, &c);
    enc_step(&e, 5u, &o);
    CHECK(e.cfg.counts >= 4u, "counts guarded");
    CHECK(e.cfg.bw_rad_s > 0.0f, "bandwidth defaulted");
    CHECK(o.theta_e_rad >= 0.0f && o.theta_e_rad < FW_TWO_PI_F, "angle valid");
    /* counts x pole pairs beyond 32 bits: float path */
    c = cfg_paper();
    c.counts = 1u << 30;
    c.pole_pairs = 8u;
    enc_init(&e, &c);
    enc_reset(&e, 1u << 28);
    enc_step(&e, 1u << 28, &o);
    CHECK_NEAR(o.theta_m_rad, FW_PI_F / 2.0f, 1e-5, "large counts: theta_m");
    CHECK(fabs(ang_diff(o.theta_e_rad, 0.0)) < 1e-4, "large counts: theta_e = 8 x pi/2 = 0");
    /* a bandwidth too high for the call period is limited */
    c = cfg_paper();
    c.bw_rad_s = 1.0e6f;
    enc_init(&e, &c);
    CHECK(e.cfg.bw_rad_s * e.cfg.ts_s <= 0.2001f, "bandwidth limited to 0.2/ts");
}

int main(void)
{
    test_angle_map();
    test_rollover();
    test_speed_accuracy();
    test_speed_step();
    test_dip();
    test_long_run();
    test_guards();
    return CHECK_DONE();
}
