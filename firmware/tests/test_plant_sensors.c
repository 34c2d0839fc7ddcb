/* Unit tests of the emulator's measurement chain (firmware/sim/plant_sensors.c: current sensors,
 * encoder) and its PRNG (firmware/sim/rng.c). */
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

/* ------------------------------------------------------------------ PRNG */

static void test_rng(void)
{
    rng_t a, b, c;
    int k, same = 1, diff = 0;
    double s1 = 0.0, s2 = 0.0, s4 = 0.0, tail = 0.0;
    const int n = 1000000;

    rng_seed(&a, 42u);
    rng_seed(&b, 42u);
    rng_seed(&c, 43u);
    for (k = 0; k < 1000; k++) {
        const double ga = rng_gauss(&a), gb = rng_gauss(&b), gc = rng_gauss(&c);
        same &= (ga == gb);
        diff += (ga != gc);
    }
    CHECK(same, "rng: same seed gives the same Gaussian sequence");
    CHECK(diff > 990, "rng: a different seed gives a different sequence");

    rng_seed(&a, 7u);
    for (k = 0; k < n; k++) {
        const double g = rng_gauss(&a);
        s1 += g;
        s2 += g * g;
        s4 += g * g * g * g;
        tail += fabs(g) > 3.0;
    }
    CHECK_NEAR(s1 / n, 0.0, 0.005, "ziggurat mean");
    CHECK_NEAR(s2 / n, 1.0, 0.005, "ziggurat variance");
    CHECK_NEAR(s4 / n, 3.0, 0.05, "ziggurat fourth moment (Gaussian: 3)");
    CHECK_NEAR(tail / n, 0.0026998, 0.0003, "ziggurat P(|x| > 3)");

    rng_seed(&a, 9u);
    s1 = s2 = 0.0;
    for (k = 0; k < 200000; k++) {
        const double g = rng_gauss_polar(&a);
        s1 += g;
        s2 += g * g;
    }
    CHECK_NEAR(s1 / 200000, 0.0, 0.01, "polar mean");
    CHECK_NEAR(s2 / 200000, 1.0, 0.01, "polar variance");

    { /* the stored ziggurat tables equal Marsaglia & Tsang's set-up recursion */
        const double m = 16777216.0, vn = 9.91256303526217e-3;
        double dn = 3.442619855899, tn = dn, q = vn / exp(-0.5 * dn * dn), wmax = 0.0, fmax = 0.0;
        int i, kmax = 0;
        uint32_t kn[128];
        double wn[128], fn[128];
        kn[0] = (uint32_t)((dn / q) * m);
        kn[1] = 0u;
        wn[0] = q / m;
        wn[127] = dn / m;
        fn[0] = 1.0;
        fn[127] = exp(-0.5 * dn * dn);
        for (i = 126; i >= 1; i--) {
            dn = sqrt(-2.0 * log(vn / dn + exp(-0.5 * dn * dn)));
            kn[i + 1] = (uint32_t)((dn / tn) * m);
            tn = dn;
            fn[i] = exp(-0.5 * dn * dn);
            wn[i] = dn / m;
        }
        for (i = 0; i < 128; i++) {
            const int dk = (int)kn[i] - (int)rng_zig_k[i];
            kmax = dk > kmax ? dk : (-dk > kmax ? -dk : kmax);
            wmax = maxd(wmax, fabs(wn[i] / rng_zig_w[i] - 1.0));
            fmax = maxd(fmax, fabs(fn[i] / rng_zig_f[i] - 1.0));
        }
        CHECK(kmax <= 1, "ziggurat k table");
        CHECK(wmax < 1e-13, "ziggurat w table");
        CHECK(fmax < 1e-13, "ziggurat f table");
    }
}

static void test_encoder(void)
{
    plant_cfg_t cfg;
    plant_t p;
    fw_meas_t m;
    fw_cmd_t off;
    int k, ok = 1;

    cfg_base(&cfg);
    cfg.enc_counts = 1000u;
    plant_init(&p, &cfg);
    plant_sample(&p, &m);
    CHECK(m.enc_count == 0u, "encoder 0 at theta_m = 0");
    for (k = 0; k < 1000; k++) {
        const double th = (k + 0.5) * TWO_PI / 1000.0;
        plant_set_mech(&p, th, 0.0, true);
        plant_sample(&p, &m);
        if (m.enc_count != (uint32_t)k)
            ok = 0;
    }
    CHECK(ok, "encoder count = floor(theta_m N / 2 pi)");
    plant_set_mech(&p, TWO_PI - 1e-9, 0.0, true);
    plant_sample(&p, &m);
    CHECK(m.enc_count == 999u, "encoder just below a full turn: N - 1");
    plant_set_mech(&p, -1e-9, 0.0, true);
    plant_sample(&p, &m);
    CHECK(m.enc_count == 999u, "encoder at a small negative angle wraps to N - 1");
    plant_set_mech(&p, 7.0 * TWO_PI + 0.5 * TWO_PI / 1000.0, 0.0, true);
    plant_sample(&p, &m);
    CHECK(m.enc_count == 0u, "encoder after whole turns");

    cfg.enc_offset_m_rad = PI;
    plant_init(&p, &cfg);
    plant_sample(&p, &m);
    CHECK(m.enc_count == 500u, "encoder offset pi: half a turn");

    /* turning backwards through zero: counts wrap from 0 to N - 1 and decrease */
    cfg.enc_offset_m_rad = 0.0;
    plant_init(&p, &cfg);
    plant_set_mech(&p, 0.6 * TWO_PI / 1000.0, -TWO_PI / 1000.0 / 50e-6 / 4.0,
                   true); /* -1/4 count per period */
    cmd_set(&off, 0, 0, 0, false, 0.0);
    {
        uint32_t seen[12];
        for (k = 0; k < 12; k++) {
            plant_sample(&p, &m);
            seen[k] = m.enc_count;
            plant_step(&p, &off);
        }
        CHECK(seen[0] == 0u && seen[2] == 0u && seen[3] == 999u && seen[6] == 999u &&
                  seen[7] == 998u && seen[11] == 997u,
              "encoder backwards through zero");
    }
}

/* ------------------------------------------------------------------ noise, quantisation, determinism */

static void test_sensors(void)
{
    plant_cfg_t cfg;
    plant_t p, q;
    fw_meas_t m, mq;
    fw_cmd_t c;
    plant_truth_t tp, tq;
    int k, same = 1, diff = 0, onlsb = 1;
    double s1 = 0.0, s2 = 0.0;

    cfg_base(&cfg);
    cfg.i_noise_a = 0.1;
    plant_init(&p, &cfg);
    for (k = 0; k < 100000; k++) {
        plant_sample(&p, &m);
        s1 += m.i_a_a;
        s2 += (double)m.i_b_a * m.i_b_a;
    }
    CHECK_NEAR(s1 / 100000, 0.0, 0.002, "current noise has zero mean");
    CHECK_NEAR(sqrt(s2 / 100000), 0.1, 0.002, "current noise std = i_noise_a");

    cfg.adc_lsb_a = 0.02;
    plant_init(&p, &cfg);
    plant_set_currents(&p, 3.3, -1.7);
    for (k = 0; k < 1000; k++) {
        double r;
        plant_sample(&p, &m);
        r = m.i_c_a / 0.02;
        if (fabs(r - floor(r + 0.5)) > 1e-4)
            onlsb = 0;
    }
    CHECK(onlsb, "ADC output on the LSB grid");
    cfg.i_noise_a = 0.0;
    plant_init(&p, &cfg);
    plant_set_currents(&p, 0.013, 0.0);
    plant_sample(&p, &m);
    CHECK_NEAR(m.i_a_a, 0.02, 1e-7, "quantisation rounds to the nearest LSB");
    CHECK_NEAR(m.v_dc_v, 540.0, 0.0, "DC-link voltage measured");

    /* determinism: same seed and commands give identical measurements and truth, bit for bit */
    cfg.i_noise_a = 0.05;
    cfg.dead_time_s = 2e-6;
    cfg.v_drop_v = 1.0;
    cfg.t_coulomb_nm = 0.05;
    cfg.seed = 1234u;
    plant_init(&p, &cfg);
    plant_init(&q, &cfg);
    for (k = 0; k < 5000; k++) {
        plant_sample(&p, &m);
        plant_sample(&q, &mq);
        if (memcmp(&m, &mq, sizeof m) != 0)
            same = 0;
        cmd_set(&c, (k * 7) % 3 == 0, (k * 5) % 4 == 1, (k % 5) == 2, (k % 400) < 350, 0.5);
        plant_step(&p, &c);
        plant_step(&q, &c);
    }
    plant_truth(&p, &tp);
    plant_truth(&q, &tq);
    CHECK(same && memcmp(&tp, &tq, sizeof tp) == 0, "same seed: identical runs, bit for bit");
    cfg.adc_lsb_a = 0.0;
    cfg.seed = 1235u;
    plant_init(&q, &cfg);
    plant_init(&p, &cfg);
    cfg.seed = 1234u;
    plant_init(&p, &cfg);
    for (k = 0; k < 100; k++) {
        plant_sample(&p, &m);
        plant_sample(&q, &mq);
        diff += m.i_a_a != mq.i_a_a;
    }
    CHECK(diff > 90, "different seed: different noise");
}

/* ------------------------------------------------------------------ mechanics */

int main(void)
{
    test_rng();
    test_encoder();
    test_sensors();
    return CHECK_DONE();
}
