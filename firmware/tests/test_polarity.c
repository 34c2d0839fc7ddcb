/* Magnet polarity at start-up (polarity.h) on the plant: with the estimate started half a turn
 * off (or on the right pole) at several rotor angles, the d-axis pulses pick the right half-turn
 * on a plant whose d axis saturates asymmetrically; on the linear plant the test ends cleanly as
 * "not resolved". The hybrid's handover (hybrid.h): the output never steps, and a disagreement
 * is latched as a loss of lock. */
#include <stdio.h>

#include "check.h"
#include "hybrid.h"
#include "polarity.h"
#include "rng.h"
#include "sensorless_loop.h"

#define ND 33
#define NQ 17
static plant_map_t map_sat;

/* psi_d = psi_f + L_d i_d (i_d <= 0), psi_f + L_d I_s tanh(i_d / I_s) (i_d > 0): the magnet's
 * flux and a positive d current add up in the iron; psi_q = L_q i_q. */
static void build_map(void)
{
    static double pd[ND * NQ], pq[ND * NQ];
    int j, k;
    const char *err;
    for (k = 0; k < NQ; k++) {
        for (j = 0; j < ND; j++) {
            const double id = -16.0 + 1.0 * j, iq = -16.0 + 2.0 * k;
            pd[k * ND + j] = 0.18 + (id <= 0.0 ? 5e-3 * id : 5e-3 * 8.0 * tanh(id / 8.0));
            pq[k * ND + j] = 12e-3 * iq;
        }
    }
    err = plant_map_build(&map_sat, ND, NQ, -16.0, 1.0, -16.0, 2.0, pd, pq);
    CHECK(err == NULL, "polarity: the test's flux map builds");
}

static pol_cfg_t pol_cfg(void)
{
    pol_cfg_t c;
    c.ts_s = 50e-6f;
    c.i_pulse_a = 6.0f;
    c.settle_s = 0.03f;
    c.pulse_s = 0.01f;
    c.release_s = 0.005f;
    /* at +-6 A: g+ = 1/(5 mH sech^2 0.75) = 335, g- = 200 1/H -> (g+ - g-)/(g+ + g-) = 0.25 */
    c.asym_expected = 0.25f;
    c.asym_min = 0.05f;
    c.conf_min = 0.8f;
    return c;
}

/* Run the test from estimate = truth + off; returns the result and the final angle error. */
static uint16_t run(const plant_map_t *map, double th_true, double off, double *err, float *asym)
{
    plant_cfg_t pc;
    rpll_cfg_t ec;
    sl_t s;
    pol_t pol;
    pol_cfg_t cfg = pol_cfg();
    pol_out_t po;
    int k;
    plant_cfg_default(&pc);
    pc.i_noise_a = 0.02;
    pc.adc_lsb_a = 0.0244140625;
    pc.map = map;
    sl_cfg_pll(&ec);
    sl_init(&s, &pc, &ec, th_true, 0.0, (float)(th_true + off));
    plant_set_mech(&s.p, s.p.theta_m_rad, 0.0, false); /* a free rotor */
    pol_init(&pol, &cfg);
    memset(&po, 0, sizeof po);
    for (k = 0; k < 3000; k++) {
        pol_in_t pi;
        sl_period(&s);
        pi.di_d_a = s.eo.di_d_a;
        pi.u_d_v = s.eo.u_d_v;
        pi.i_d_a = s.eo.i_d_mid_a;
        pi.conf = s.eo.conf;
        pi.excited = s.eo.excited;
        pol_step(&pol, &pi, &po);
        if (po.flip_now) {
            rpll_flip(&s.e);
        }
        s.i_d_ref_a = po.active ? po.i_d_ref_a : 0.0f;
        if (!po.active) {
            break;
        }
    }
    for (k = 0; k < 200; k++) {
        sl_period(&s);
    }
    *err = sl_err(&s);
    *asym = po.asym;
    return po.result;
}

static void test_polarity_found(void)
{
    rng_t r;
    int n, ok = 0, n_flip = 0;
    double worst = 0.0;
    char msg[160];
    rng_seed(&r, 23u);
    for (n = 0; n < 8; n++) {
        const double th = 6.283185307179586 * rng_uniform(&r);
        const double off = (n % 2 ? 3.14159265358979 : 0.0) + 0.3 * (rng_uniform(&r) - 0.5);
        double err;
        float asym;
        uint16_t res = run(&map_sat, th, off, &err, &asym);
        if ((res == POL_KEPT || res == POL_FLIPPED) && fabs(err) < 0.1) {
            ok++;
        }
        n_flip += res == POL_FLIPPED;
        worst = fabs(err) > worst ? fabs(err) : worst;
        if (n == 0) {
            printf("  polarity: asymmetry measured %.3f (expected 0.25)\n", asym);
        }
    }
    snprintf(msg, sizeof msg,
             "polarity: right half-turn at 8 of 8 random angles (%d; %d flips; worst %.3f rad)", ok,
             n_flip, worst);
    printf("  %s\n", msg);
    CHECK(ok == 8, msg);
    CHECK(n_flip == 4, "polarity: exactly the estimates started on the wrong pole were flipped");
}

static void test_polarity_linear_plant(void)
{
    double err;
    float asym;
    uint16_t res = run(NULL, 1.0, 3.14159265358979, &err, &asym);
    printf("  polarity on a linear plant: result %u, asymmetry %.4f\n", (unsigned)res,
           (double)asym);
    CHECK(res == POL_UNRESOLVED, "polarity: a plant that does not saturate is 'not resolved'");
    CHECK(fabsf(asym) < 0.05f, "polarity: no asymmetry measured on the linear plant");
}

static void test_decide(void)
{
    pol_cfg_t c = pol_cfg();
    float a;
    CHECK(pol_decide(&c, 335.0f, 200.0f, &a) == POL_KEPT, "decide: expected sign kept");
    CHECK_NEAR(a, 0.2523, 1e-3, "decide: asymmetry");
    CHECK(pol_decide(&c, 200.0f, 335.0f, &a) == POL_FLIPPED, "decide: opposite sign flips");
    CHECK(pol_decide(&c, 200.0f, 201.0f, &a) == POL_UNRESOLVED, "decide: too small");
    c.asym_expected = -0.29f; /* a map whose negative side saturates (paper-a-ipmsm.csv) */
    CHECK(pol_decide(&c, 177.0f, 320.0f, &a) == POL_KEPT, "decide: the map's own signature");
}

/* The hybrid of the tests: 50 us periods, 4 pole pairs, the band pll_on_rpm .. mras_on_rpm, a
 * 20 ms blend, 0.3 rad for 20 ms of disagreement, a confidence of 0.5 for 50 ms. */
static void hyb_test_init(hyb_t *h, hyb_cfg_t *c, float pll_on_rpm, float mras_on_rpm)
{
    c->ts_s = 50e-6f;
    c->pole_pairs = 4u;
    c->pll_on_rpm = pll_on_rpm;
    c->mras_on_rpm = mras_on_rpm;
    c->blend_s = 0.02f;
    c->disagree_rad = 0.3f;
    c->disagree_s = 0.02f;
    c->conf_min = 0.5f;
    c->lost_s = 0.05f;
    hyb_init(h, c);
}

/* Hybrid: a slow speed ramp through the band with a constant offset between the estimators;
 * the output moves by at most the offset times ts/blend per period. */
static void test_hybrid_bumpless(void)
{
    hyb_cfg_t c;
    hyb_t h;
    hyb_in_t in;
    hyb_out_t o;
    int k;
    double th = 0.0, prev = 0.0, max_step = 0.0;
    bool reached = false, back = false;
    hyb_test_init(&h, &c, 200.0f, 300.0f);
    for (k = 0; k < 60000; k++) { /* 0 -> 600 -> 0 r/min over 3 s */
        const double rpm = k < 30000 ? 600.0 * k / 30000.0 : 600.0 * (60000 - k) / 30000.0;
        const double w = rpm * 4.0 * 3.14159265358979 / 30.0;
        th += w * 50e-6;
        in.theta_pll_rad = (float)fmod(th, 6.283185307179586);
        in.omega_pll_rad_s = (float)w;
        in.conf_pll = 0.95f;
        in.theta_mras_rad = (float)fmod(th + 0.05, 6.283185307179586);
        in.omega_mras_rad_s = (float)w;
        in.mras_locked = true;
        hyb_step(&h, &in, &o);
        if (k > 0) {
            double d =
                fmod((double)o.theta_e_rad - prev - w * 50e-6 + 9.42477796, 6.283185307179586) -
                3.14159265358979;
            max_step = fabs(d) > max_step ? fabs(d) : max_step;
        }
        prev = o.theta_e_rad;
        reached = reached || o.w_mras >= 1.0f;
        back = reached && o.w_mras <= 0.0f;
    }
    CHECK(reached && back, "hybrid: hands over to the MRAS and back");
    CHECK(max_step < 0.05 * 50e-6 / 0.02 * 1.01, "hybrid: no angle step at the handovers");
    CHECK(o.lock == HYB_LOCK_OK, "hybrid: no loss of lock when the estimators agree");
    /* a disagreement above pll_on_rpm for longer than disagree_s is latched */
    for (k = 0; k < 1000; k++) {
        in.theta_pll_rad = 0.0f;
        in.omega_pll_rad_s = 300.0f;
        in.theta_mras_rad = 0.8f;
        in.omega_mras_rad_s = 300.0f;
        hyb_step(&h, &in, &o);
    }
    CHECK(o.lock == HYB_LOCK_DISAGREE, "hybrid: disagreement is a loss of lock");
}

/* Hybrid: the MRAS carries the angle (w = 1, 0.1 rad ahead of the PLL), then drops lock and its
 * angle jumps by about pi every few periods (an unlocked MRAS): the output heads for the PLL's
 * angle from the last locked difference and never follows the unlocked one. */
static void test_hybrid_mras_drops_lock(void)
{
    hyb_cfg_t c;
    hyb_t h;
    hyb_in_t in;
    hyb_out_t o;
    int k;
    double max_off = 0.0, prev_w = 1.0;
    bool falling = true;
    hyb_test_init(&h, &c, 150.0f, 250.0f);
    in.theta_pll_rad = 1.0f;
    in.omega_pll_rad_s = 400.0f * 4.0f * 3.14159265f / 30.0f; /* 400 r/min */
    in.conf_pll = 0.95f;
    in.omega_mras_rad_s = in.omega_pll_rad_s;
    in.theta_mras_rad = 1.1f;
    in.mras_locked = true;
    for (k = 0; k < 1000; k++) { /* 50 ms: the MRAS takes over */
        hyb_step(&h, &in, &o);
    }
    CHECK(o.w_mras >= 1.0f, "hybrid: the locked MRAS carries the angle above the band");
    CHECK_NEAR(o.theta_e_rad, 1.1, 1e-5, "hybrid: the MRAS's angle");
    in.mras_locked = false;
    for (k = 0; k < 1000; k++) { /* unlocked: its angle alternates between 1.1 and 1.1 + 3 */
        in.theta_mras_rad = (k / 3) % 2 ? 4.1f : 1.1f;
        hyb_step(&h, &in, &o);
        max_off = fabs((double)o.theta_e_rad - 1.0) > max_off ? fabs((double)o.theta_e_rad - 1.0)
                                                              : max_off;
        falling = falling && o.w_mras <= prev_w;
        prev_w = o.w_mras;
    }
    CHECK(falling && o.w_mras <= 0.0f, "hybrid: w heads for 0 once the MRAS drops lock");
    CHECK(max_off <= 0.1 + 1e-5, "hybrid: the output never follows the unlocked MRAS");
    CHECK_NEAR(o.theta_e_rad, 1.0, 1e-6, "hybrid: the PLL's angle once w is 0");
    CHECK(o.lock == HYB_LOCK_OK, "hybrid: an unlocked MRAS is no disagreement");
    /* the MRAS back in lock and carrying again; then its angle jumps by 3 rad while it still
     * reports lock (for 10 periods, less than disagree_s): the output keeps the last difference */
    in.theta_mras_rad = 1.1f;
    in.mras_locked = true;
    for (k = 0; k < 1000; k++) {
        hyb_step(&h, &in, &o);
    }
    CHECK(o.w_mras >= 1.0f, "hybrid: the MRAS carries again once back in lock");
    max_off = 0.0;
    for (k = 0; k < 500; k++) { /* a handover takes 400 periods */
        in.theta_mras_rad = 4.1f;
        in.mras_locked = k < 10;
        hyb_step(&h, &in, &o);
        max_off = fabs((double)o.theta_e_rad - 1.0) > max_off ? fabs((double)o.theta_e_rad - 1.0)
                                                              : max_off;
    }
    CHECK(max_off <= 0.1 + 1e-5, "hybrid: a jump of the still-locked MRAS is not followed");
    CHECK(o.w_mras <= 0.0f, "hybrid: and the PLL takes the angle back");
    CHECK(o.lock == HYB_LOCK_OK, "hybrid: a jump shorter than disagree_s is no loss of lock");
}

int main(void)
{
    build_map();
    test_decide();
    test_polarity_found();
    test_polarity_linear_plant();
    test_hybrid_bumpless();
    test_hybrid_mras_drops_lock();
    return CHECK_DONE();
}
