/* Plant speed benchmark (not a unit test; make does not run it). Build and run by hand:
 *   cc -std=c99 -O2 -Wall -Wextra -Werror -Icore -Isim tests/bench_plant.c sim/plant.c sim/rng.c -lm -o /tmp/bench_plant
 *   /tmp/bench_plant [periods]
 * Measures plant_sample + plant_step per control period (Ts = 50 us) for paper A's IPMSM at 1000 r/min
 * under a closed current loop (a simple hysteresis choice of the switch state, cheap enough not to
 * disturb the figure), with sensor noise, ADC quantisation and the inverter distortion on. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <math.h>

#include "plant.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* pick the switch state whose voltage vector points closest to the current error (a bang-bang
 * current loop in the stationary frame): cheap, closed loop, switches most periods like FCS-MPC */
static void choose(const fw_meas_t *m, double iar, double ibr, fw_cmd_t *c)
{
    static const double vx[8] = {0, 1, 0.5, -0.5, -1, -0.5, 0.5, 0};
    static const double vy[8] = {0, 0, 0.866, 0.866, 0, -0.866, -0.866, 0};
    static const int sa[8] = {0, 1, 1, 0, 0, 0, 1, 1}, sb[8] = {0, 0, 1, 1, 1, 0, 0, 1}, sc[8] = {0, 0, 0, 0, 1, 1, 1, 1};
    const double ea = iar - m->i_a_a, eb = ibr - (m->i_a_a + 2.0 * m->i_b_a) * 0.57735026919;
    double best = -1e30;
    int k, kb = 0;
    for (k = 0; k < 8; k++) {
        const double sc_ = vx[k] * ea + vy[k] * eb;
        if (sc_ > best) { best = sc_; kb = k; }
    }
    if (ea * ea + eb * eb < 0.25) kb = 0;
    c->s_a = (uint16_t)sa[kb]; c->s_b = (uint16_t)sb[kb]; c->s_c = (uint16_t)sc[kb];
}

static double run(plant_cfg_t *cfg, long n, int closed_loop)
{
    plant_t p;
    fw_meas_t m;
    fw_cmd_t c = {0, 0, 0, true, 0.0f}, cprev = c;
    double t0, t1, sink = 0.0;
    long k;
    uint32_t lcg = 12345u;
    plant_init(&p, cfg);
    plant_set_mech(&p, 0.0, 1000.0 * 3.14159265358979 / 30.0, true);
    t0 = now_s();
    for (k = 0; k < n; k++) {
        plant_sample(&p, &m);
        if (closed_loop) {
            const double th = 4.0 * p.theta_m_rad;   /* reference: i_q = 10 A, rotating */
            choose(&m, -10.0 * sin(th), 10.0 * cos(th), &c);
        } else {
            lcg = lcg * 1664525u + 1013904223u;
            c.s_a = (uint16_t)((lcg >> 29) & 1u); c.s_b = (uint16_t)((lcg >> 30) & 1u); c.s_c = (uint16_t)(lcg >> 31);
        }
        plant_step(&p, &cprev);
        cprev = c;
        sink += m.i_a_a;
    }
    t1 = now_s();
    if (sink == 12345.678) printf("!");
    return (t1 - t0) / (double)n * 1e9;
}

int main(int argc, char **argv)
{
    const long n = argc > 1 ? atol(argv[1]) : 4000000L;
    plant_cfg_t cfg;
    double ns_loop, ns;
    int rep;
    for (rep = 0; rep < 2; rep++) {
        plant_cfg_default(&cfg);
        cfg.enc_counts = 10000u;
        ns = run(&cfg, n, 0);
        printf("ideal sensors/inverter, substeps 1, random states : %6.1f ns/period\n", ns);
        cfg.i_noise_a = 0.05; cfg.adc_lsb_a = 40.0 / 4096.0;
        cfg.dead_time_s = 2e-6; cfg.v_drop_v = 1.5; cfg.i_dt_a = 0.5;
        ns = run(&cfg, n, 0);
        printf("noise+ADC+dead time, substeps 1, random states    : %6.1f ns/period\n", ns);
        cfg.substeps = 2;
        ns = run(&cfg, n, 0);
        printf("noise+ADC+dead time, substeps 2, random states    : %6.1f ns/period\n", ns);
        cfg.substeps = 1;
        ns_loop = run(&cfg, n, 1);
        printf("noise+ADC+dead time, substeps 1, bang-bang loop   : %6.1f ns/period (incl. the loop's own sin/cos)\n", ns_loop);
    }
    printf("real-time factor of the plant alone at Ts = 50 us: %.0fx\n", 50e3 / ns);
    return 0;
}
