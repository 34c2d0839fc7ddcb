/* Rig effects in the plant (docs/rigs.md): delay, saturation dynamics, thermal coefficients, the
 * flux map interpolation, and "off is ideal" at the plant level. */
#include <math.h>
#include <string.h>

#include "check.h"
#include "plant.h"

static const int SA[8] = { 0, 1, 1, 0, 0, 0, 1, 1 }, SB[8] = { 0, 0, 1, 1, 1, 0, 0, 1 },
                 SC[8] = { 0, 0, 0, 0, 1, 1, 1, 1 };

static fw_cmd_t cmd_of(int k)
{
    fw_cmd_t c;
    memset(&c, 0, sizeof c);
    c.s_a = (uint16_t)SA[k];
    c.s_b = (uint16_t)SB[k];
    c.s_c = (uint16_t)SC[k];
    c.pwm_on = true;
    return c;
}

/* a fixed pseudo-random switch sequence, the same for every run */
static int seq_at(int n)
{
    return (int)((1103515245u * (unsigned)(n + 7) + 12345u) >> 16) % 8;
}

#define N 400
static void record(const plant_cfg_t *cfg, double ia_meas[N], double ia_true[N])
{
    static plant_t p;
    plant_truth_t t;
    fw_meas_t m;
    int n;
    plant_init(&p, cfg);
    plant_set_mech(&p, 0.3, 100.0, true);
    for (n = 0; n < N; n++) {
        fw_cmd_t c = cmd_of(n < 20 ? 0 : seq_at(n));
        plant_sample(&p, &m);
        plant_truth(&p, &t);
        ia_meas[n] = m.i_a_a;
        ia_true[n] = t.i_a_a;
        plant_step(&p, &c);
    }
}

static void test_delay(void)
{
    plant_cfg_t cfg;
    static double m0[N], t0[N], m1[N], t1[N];
    int n, ok;
    plant_cfg_default(&cfg);
    cfg.v_dc_v = 100.0;
    record(&cfg, m0, t0);
    /* sample delay of 3 periods: the measurement is the ideal one three periods later */
    cfg.sample_delay_s = 3.0 * cfg.ts_s;
    record(&cfg, m1, t1);
    ok = 1;
    for (n = 3; n < N; n++) {
        ok &= fabs(m1[n] - (double)(float)t0[n - 3]) < 1e-6 && t1[n] == t0[n];
    }
    CHECK(ok,
          "sample delay 3 Ts: measured current = true current 3 periods earlier, plant unchanged");
    /* half a period: linear interpolation between boundaries */
    cfg.sample_delay_s = 0.5 * cfg.ts_s;
    record(&cfg, m1, t1);
    ok = 1;
    for (n = 1; n < N; n++) {
        ok &= fabs(m1[n] - 0.5 * (t0[n] + t0[n - 1])) < 1e-5;
    }
    CHECK(ok, "sample delay Ts/2: the mean of the two boundary currents");
    /* PWM update delay of 2 periods: the true current response is shifted by 2 periods */
    cfg.sample_delay_s = 0.0;
    cfg.pwm_delay_periods = 2;
    plant_cfg_default(&cfg);
    cfg.v_dc_v = 100.0;
    cfg.pwm_delay_periods = 2;
    {
        static plant_t p;
        plant_truth_t t;
        fw_meas_t m;
        static double ts[N];
        plant_init(&p, &cfg);
        plant_set_mech(&p, 0.3, 0.0, true);
        for (n = 0; n < N; n++) {
            fw_cmd_t c = cmd_of(n < 20 ? 0 : seq_at(n));
            plant_sample(&p, &m);
            plant_truth(&p, &t);
            ts[n] = t.i_a_a;
            plant_step(&p, &c);
        }
        plant_cfg_default(&cfg);
        cfg.v_dc_v = 100.0;
        plant_init(&p, &cfg);
        plant_set_mech(&p, 0.3, 0.0, true);
        ok = 1;
        for (n = 0; n < N - 2; n++) {
            fw_cmd_t c = cmd_of(n < 20 ? 0 : seq_at(n));
            plant_truth(&p, &t);
            ok &= fabs(ts[n + 2] - t.i_a_a) < 1e-12;
            plant_step(&p, &c);
        }
        CHECK(ok,
              "PWM delay 2 periods (rotor at rest): the current response comes 2 periods later");
    }
}

/* analytic saturating map: psi_q = Lq0 iq / sqrt(1 + (iq/8)^2) (incremental L_q falls with |i_q|),
 * psi_d = psi_f + Ld id */
static double psi_q_of(double iq)
{
    return 0.012 * iq / sqrt(1.0 + iq * iq / 64.0);
}
static double lq_of(double iq)
{
    return 0.012 / pow(1.0 + iq * iq / 64.0, 1.5);
}

static plant_map_t map;

static void test_saturation(void)
{
    static double pd[41 * 61], pq[41 * 61];
    plant_cfg_t cfg;
    static plant_t p;
    int j, k, ok = 1;
    double l[4], a, b;
    for (k = 0; k < 61; k++) {
        for (j = 0; j < 41; j++) {
            const double id = -20.0 + 0.5 * j, iq = -15.0 + 0.5 * k;
            pd[k * 41 + j] = 0.18 + 0.005 * id;
            pq[k * 41 + j] = psi_q_of(iq);
        }
    }
    CHECK(plant_map_build(&map, 41, 61, -20.0, 0.5, -15.0, 0.5, pd, pq) == NULL, "map builds");
    CHECK(plant_map_build(&map, 1, 61, -20.0, 0.5, -15.0, 0.5, pd, pq) != NULL,
          "map rejects 1 node");
    CHECK(plant_map_build(&map, 41, 61, -20.0, 0.5, -15.0, 0.5, pd, pq) == NULL,
          "map builds again");
    CHECK_NEAR(map.psi_f_wb, 0.18, 1e-12, "map psi_f = psi_d(0, 0)");
    for (k = 0; k < 40; k++) { /* between the nodes too */
        const double iq = -14.0 + 0.7 * k;
        plant_map_eval(&map, -3.3, iq, &a, &b, l);
        ok &= fabs(b - psi_q_of(iq)) < 1e-5 && fabs(l[3] - lq_of(iq)) < 0.01 * lq_of(iq) &&
              fabs(l[0] - 0.005) < 1e-9;
        if (k == 20) {
            printf("  map at i_q %.1f A: psi_q error %.2e Wb, L_q error %.2f %%\n", iq,
                   b - psi_q_of(iq), 100.0 * (l[3] - lq_of(iq)) / lq_of(iq));
        }
    }
    CHECK(ok, "map: psi_q and incremental L_q between the nodes");
    plant_map_eval(&map, -25.0, 0.0, &a, &b, l);
    CHECK_NEAR(a, 0.18 - 0.125, 1e-9, "map: linear beyond the grid (psi_d at i_d = -25 A)");
    /* dynamics: at the operating point (0, iq0), rotor held at standstill, a q-voltage step:
     * di_q/dt = u_q / L_q,inc(i_q), the map's incremental inductance along the way */
    plant_cfg_default(&cfg);
    cfg.map = &map;
    cfg.r_s_ohm = 0.0;
    ok = 1;
    for (k = 0; k < 5; k++) {
        const double iq0 = 3.0 * k, u = 10.0;
        double diq;
        plant_init(&p, &cfg);
        plant_set_mech(&p, 0.0, 0.0, true);
        plant_set_currents(&p, 0.0, iq0);
        plant_step_udq(&p, 0.0, u, 0.0);
        diq = (p.i_q_a - iq0) / cfg.ts_s;
        /* exactly: the flux change over the period is the volt-seconds (R = 0, rotor at rest) */
        ok &= fabs((psi_q_of(p.i_q_a) - psi_q_of(iq0)) - u * cfg.ts_s) < 0.005 * u * cfg.ts_s;
        printf("  i_q %4.1f A: L_q from the current slope %.3f mH, map %.3f mH\n", iq0,
               1e3 * u / diq, 1e3 * lq_of(iq0));
    }
    CHECK(ok, "saturation: the current slope follows the incremental L_q of the map (0..12 A)");
    CHECK(lq_of(12.0) < 0.6 * lq_of(0.0), "the test map saturates");
}

static void test_thermal_and_off(void)
{
    plant_cfg_t cfg, off;
    static plant_t p, q;
    plant_truth_t t, u;
    fw_meas_t m1, m2;
    int n, same = 1;
    plant_cfg_default(&cfg);
    cfg.thermal_on = 1;
    cfg.temp_winding0_c = 125.0;
    cfg.temp_magnet0_c = 75.0;
    plant_init(&p, &cfg);
    plant_truth(&p, &t);
    CHECK_NEAR(t.r_s_ohm, 0.9 * (1.0 + 0.00393 * 100.0), 1e-12, "R at 125 degC");
    CHECK_NEAR(t.psi_f_wb, 0.18 * (1.0 - 0.001 * 50.0), 1e-12, "psi_f at 75 degC");
    /* every effect parameter set but off: identical to the default plant, bit for bit */
    plant_cfg_default(&off);
    off.temp_ref_c = 40.0;
    off.c_winding_j_k = 3.0;
    off.cog_order_e = 9;
    off.dc_r_src_ohm = 3.0;
    off.dc_grid_hz = 60.0;
    plant_cfg_default(&cfg);
    plant_init(&p, &cfg);
    plant_init(&q, &off);
    plant_set_mech(&p, 0.2, 50.0, false);
    plant_set_mech(&q, 0.2, 50.0, false);
    for (n = 0; n < 2000; n++) {
        fw_cmd_t c = cmd_of(seq_at(n));
        plant_sample(&p, &m1);
        plant_sample(&q, &m2);
        plant_step(&p, &c);
        plant_step(&q, &c);
        plant_truth(&p, &t);
        plant_truth(&q, &u);
        same &= memcmp(&m1, &m2, sizeof m1) == 0 && t.i_d_a == u.i_d_a && t.i_q_a == u.i_q_a &&
                t.omega_m_rad_s == u.omega_m_rad_s && t.theta_m_rad == u.theta_m_rad;
    }
    CHECK(same, "effects off (their parameters set): bit-identical to the default plant");
}

int main(void)
{
    test_delay();
    test_saturation();
    test_thermal_and_off();
    return CHECK_DONE();
}
