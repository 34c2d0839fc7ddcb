/* The sensorless angle source (sensorless.h) on the plant with the MPCC: a start from rest at an
 * unknown angle gives a valid angle on the right pole (saturating plant) or a latched "polarity
 * not resolved" (linear plant); a slip of the rotor against the estimate is a latched loss of
 * lock, reported once. */
#include <stdio.h>

#include "check.h"
#include "sensorless.h"
#include "sensorless_loop.h"

#define ND 33
#define NQ 17
static plant_map_t map_sat, map_round;

static void build_map(void)
{
    static double pd[ND * NQ], pq[ND * NQ];
    int j, k;
    for (k = 0; k < NQ; k++) {
        for (j = 0; j < ND; j++) {
            const double id = -16.0 + 1.0 * j, iq = -16.0 + 2.0 * k;
            pd[k * ND + j] = 0.18 + (id <= 0.0 ? 5e-3 * id : 5e-3 * 8.0 * tanh(id / 8.0));
            pq[k * ND + j] = 12e-3 * iq;
        }
    }
    CHECK(plant_map_build(&map_sat, ND, NQ, -16.0, 1.0, -16.0, 2.0, pd, pq) == NULL, "map");
    /* no saliency at all (L_d = L_q = 5 mH): the ripple carries no angle */
    for (k = 0; k < NQ; k++) {
        for (j = 0; j < ND; j++) {
            pd[k * ND + j] = 0.18 + 5e-3 * (-16.0 + 1.0 * j);
            pq[k * ND + j] = 5e-3 * (-16.0 + 2.0 * k);
        }
    }
    CHECK(plant_map_build(&map_round, ND, NQ, -16.0, 1.0, -16.0, 2.0, pd, pq) == NULL, "map");
}

typedef struct {
    plant_t p;
    mpcc_t m;
    snl_t s;
    mpcc_out_t mo;
    snl_out_t so;
    fw_cmd_t cmd_prev;
    float th_used, w_used;
    int n_lost_events, n_pol_events;
} rig_t;

static void rig_init(rig_t *r, const plant_map_t *map, double th_true)
{
    plant_cfg_t pc;
    snl_cfg_t c;
    mpcc_cfg_t mc;
    memset(r, 0, sizeof(*r));
    plant_cfg_default(&pc);
    pc.i_noise_a = 0.02;
    pc.adc_lsb_a = 0.0244140625;
    pc.map = map;
    plant_init(&r->p, &pc);
    plant_set_mech(&r->p, th_true / 4.0, 0.0, false);
    mpcc_cfg_default(&mc);
    mpcc_init(&r->m, &mc);
    memset(&c, 0, sizeof c);
    c.mode = SNL_MODE_PLL;
    sl_cfg_pll(&c.pll);
    c.pol.ts_s = 50e-6f;
    c.pol.i_pulse_a = 6.0f;
    c.pol.settle_s = 0.03f;
    c.pol.pulse_s = 0.01f;
    c.pol.release_s = 0.005f;
    c.pol.asym_expected = 0.25f;
    c.pol.asym_min = 0.05f;
    c.pol.conf_min = 0.8f;
    c.hyb.ts_s = 50e-6f;
    c.hyb.pole_pairs = 4u;
    c.hyb.pll_on_rpm = 150.0f;
    c.hyb.mras_on_rpm = 250.0f;
    c.hyb.blend_s = 0.02f;
    c.hyb.disagree_rad = 0.3f;
    c.hyb.disagree_s = 0.02f;
    c.hyb.conf_min = 0.5f;
    c.hyb.lost_s = 0.05f;
    snl_init(&r->s, &c);
}

static void rig_period(rig_t *r, float i_q_ref)
{
    fw_meas_t meas;
    snl_in_t in;
    mpcc_in_t mi;
    fw_cmd_t cmd;
    const float thm = r->th_used + 0.5f * r->w_used * 50e-6f;
    float c, s;
    plant_sample(&r->p, &meas);
    memset(&in, 0, sizeof in);
    tf_clarke2(meas.i_a_a, meas.i_b_a, &in.i_alpha_a, &in.i_beta_a);
    tf_inv_park(r->mo.u_d_avg_v, r->mo.u_q_avg_v, cosf(thm), sinf(thm), &in.u_alpha_prev_v,
                &in.u_beta_prev_v);
    in.u_valid = true;
    snl_step(&r->s, &in, &r->so);
    r->n_lost_events += r->so.lock_lost_now;
    r->n_pol_events += r->so.pol_done_now;
    r->th_used = r->so.theta_e_rad;
    r->w_used = r->so.omega_e_rad_s;
    c = cosf(r->th_used);
    s = sinf(r->th_used);
    memset(&mi, 0, sizeof mi);
    tf_park(in.i_alpha_a, in.i_beta_a, c, s, &mi.i_d_a, &mi.i_q_a);
    mi.i_d_ref_a = r->so.i_d_inject_a;
    mi.i_q_ref_a = r->so.startup ? 0.0f : i_q_ref;
    mi.theta_e_rad = r->th_used;
    mi.omega_e_rad_s = r->w_used;
    mi.v_dc_v = meas.v_dc_v;
    mi.r_s_ohm = 0.9f;
    mi.l_d_h = 5e-3f;
    mi.l_q_h = 12e-3f;
    mi.psi_f_wb = 0.18f;
    mpcc_step_cs(&r->m, &mi, c, s, &r->mo);
    memset(&cmd, 0, sizeof cmd);
    cmd.s_a = r->mo.s_a;
    cmd.s_b = r->mo.s_b;
    cmd.s_c = r->mo.s_c;
    cmd.pwm_on = true;
    plant_step(&r->p, &r->cmd_prev);
    r->cmd_prev = cmd;
}

static double err_of(const rig_t *r)
{
    double d = fmod((double)r->th_used - r->p.theta_m_rad * 4.0, 6.283185307179586);
    return d > 3.14159265358979 ? d - 6.283185307179586
                                : (d <= -3.14159265358979 ? d + 6.283185307179586 : d);
}

static void test_start_saturating(void)
{
    static rig_t r;
    int k, started = 0;
    rig_init(&r, &map_sat, 2.5);
    for (k = 0; k < 3000; k++) {
        rig_period(&r, 0.0f);
        if (!started && r.so.valid) {
            started = k;
        }
    }
    printf("  start: valid after %.1f ms, result %u, error %.3f rad\n", started * 0.05,
           (unsigned)r.so.pol_result, err_of(&r));
    CHECK(started > 0 && r.so.valid, "sensorless: valid after the polarity test");
    CHECK(r.so.pol_result == POL_KEPT || r.so.pol_result == POL_FLIPPED, "sensorless: resolved");
    CHECK(fabs(err_of(&r)) < 0.1, "sensorless: on the rotor's d axis");
    CHECK(r.n_pol_events == 1 && r.n_lost_events == 0, "sensorless: one polarity report");
    /* the saliency vanishes (a motor the estimator cannot see): the confidence falls and the
     * loss of lock is latched, reported once, and stays */
    r.p.cfg.map = &map_round;
    for (k = 0; k < 4000; k++) {
        rig_period(&r, 2.0f);
        if (k == 400) {
            CHECK(r.so.lock == SNL_LOCK_OK, "sensorless: not lost within 20 ms");
        }
    }
    printf("  saliency gone: lock %u, valid %d, confidence %.2f\n", (unsigned)r.so.lock,
           (int)r.so.valid, (double)r.so.conf);
    CHECK(r.so.lock == SNL_LOCK_LOW_CONF && !r.so.valid, "sensorless: loss of lock latched");
    CHECK(r.n_lost_events == 1, "sensorless: the loss is reported once");
    r.p.cfg.map = &map_sat;
    for (k = 0; k < 2000; k++) {
        rig_period(&r, 2.0f);
    }
    CHECK(r.so.lock == SNL_LOCK_LOW_CONF && !r.so.valid, "sensorless: stays lost (latched)");
}

static void test_start_linear(void)
{
    static rig_t r;
    int k;
    rig_init(&r, NULL, 1.0);
    for (k = 0; k < 3000; k++) {
        rig_period(&r, 0.0f);
    }
    CHECK(r.so.pol_result == POL_UNRESOLVED, "sensorless: linear plant, polarity not resolved");
    CHECK(r.so.lock == SNL_LOCK_POLARITY && !r.so.valid, "sensorless: latched, never valid");
    CHECK(r.n_lost_events == 1 && r.n_pol_events == 1, "sensorless: reported once each");
}

int main(void)
{
    build_map();
    test_start_saturating();
    test_start_linear();
    return CHECK_DONE();
}
