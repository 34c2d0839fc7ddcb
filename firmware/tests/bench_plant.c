/* Plant speed benchmark (not a unit test: make does not run it). Build and run by hand, from firmware/:
 *   cc -std=c99 -O3 -Wall -Wextra -Werror -Icore -Isim tests/bench_plant.c sim/plant*.c sim/rng.c -lm -o bench_plant
 *   ./bench_plant [periods]
 * Times plant_sample + plant_step per control period (Ts = 50 us) for paper A's IPMSM at 1000 r/min
 * (speed held by the dyno), replaying the switch sequence of a bang-bang current loop (i_d = 0,
 * i_q = 10 A) recorded beforehand, so that the controller's own cost is not in the figure but the
 * currents, the switching pattern and the branch behaviour are those of a closed loop (FCS-MPC
 * switches most legs most periods like this). Each case is run 5 times; the fastest is reported
 * (the machine may be shared). */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "plant.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static const int SA[8] = { 0, 1, 1, 0, 0, 0, 1, 1 }, SB[8] = { 0, 0, 1, 1, 1, 0, 0, 1 },
                 SC[8] = { 0, 0, 0, 0, 1, 1, 1, 1 };

/* the switch state whose voltage vector points closest to the current error (stationary frame) */
static int choose(const fw_meas_t *m, double iar, double ibr)
{
    static const double vx[8] = { 0, 1, 0.5, -0.5, -1, -0.5, 0.5, 0 };
    static const double vy[8] = { 0, 0, 0.866, 0.866, 0, -0.866, -0.866, 0 };
    const double ea = iar - m->i_a_a, eb = ibr - (m->i_a_a + 2.0 * m->i_b_a) * 0.57735026919;
    double best = -1e30;
    int k, kb = 0;
    for (k = 1; k < 7; k++) {
        const double s = vx[k] * ea + vy[k] * eb;
        if (s > best) {
            best = s;
            kb = k;
        }
    }
    return ea * ea + eb * eb < 0.25 ? 0 : kb;
}

static void record(const plant_cfg_t *cfg, unsigned char *seq, long n)
{
    plant_t p;
    fw_meas_t m;
    fw_cmd_t c = { FW_CMD_STATES, 0, 0, 0, 0.0f, 0.0f, 0.0f, true, 0.0f };
    long k;
    plant_init(&p, cfg);
    plant_set_mech(&p, 0.0, 1000.0 * 3.14159265358979 / 30.0, true);
    for (k = 0; k < n; k++) {
        const double th = 4.0 * p.theta_m_rad;
        plant_sample(&p, &m);
        seq[k] = (unsigned char)choose(&m, -10.0 * sin(th), 10.0 * cos(th));
        c.s_a = (uint16_t)SA[seq[k]];
        c.s_b = (uint16_t)SB[seq[k]];
        c.s_c = (uint16_t)SC[seq[k]];
        plant_step(&p, &c);
    }
}

static double replay(const plant_cfg_t *cfg, const unsigned char *seq, long n, double *irms,
                     double *sw)
{
    plant_t p;
    fw_meas_t m;
    fw_cmd_t c = { FW_CMD_STATES, 0, 0, 0, 0.0f, 0.0f, 0.0f, true, 0.0f };
    double t0, t1, sink = 0.0;
    long k;
    int prev = 0;
    plant_init(&p, cfg);
    plant_set_mech(&p, 0.0, 1000.0 * 3.14159265358979 / 30.0, true);
    *sw = 0.0;
    t0 = now_s();
    for (k = 0; k < n; k++) {
        plant_sample(&p, &m);
        c.s_a = (uint16_t)SA[seq[k]];
        c.s_b = (uint16_t)SB[seq[k]];
        c.s_c = (uint16_t)SC[seq[k]];
        plant_step(&p, &c);
        sink += (double)m.i_a_a * m.i_a_a;
        *sw += (SA[seq[k]] != SA[prev]) + (SB[seq[k]] != SB[prev]) + (SC[seq[k]] != SC[prev]);
        prev = seq[k];
    }
    t1 = now_s();
    *irms = sqrt(sink / (double)n);
    *sw /= (double)n;
    return (t1 - t0) / (double)n * 1e9;
}

/* a saturating map of paper A's size (18 x 33 nodes over -17..1 A, -17..17 A) */
static plant_map_t bench_map;
static void build_map(void)
{
    static double pd[18 * 33], pq[18 * 33];
    int j, k;
    for (k = 0; k < 33; k++) {
        for (j = 0; j < 18; j++) {
            const double id = -17.0 + j, iq = -17.0 + k;
            pd[k * 18 + j] = 0.18 + 0.005 * 4.0 * tanh(id / 4.0) - 1e-5 * iq * iq;
            pq[k * 18 + j] = 0.006 * iq + 0.006 * 6.0 * tanh(iq / 6.0) - 2e-5 * id * iq;
        }
    }
    plant_map_build(&bench_map, 18, 33, -17.0, 1.0, -17.0, 1.0, pd, pq);
}

#define N_CASES 12
int main(int argc, char **argv)
{
    static const char *names[N_CASES] = { "ideal inverter and sensors, 1 RK4 substep        ",
                                          "noise + ADC + dead time + drop (the base below)  ",
                                          "base, 2 RK4 substeps                             ",
                                          "base + saturation (18 x 33 flux map)             ",
                                          "base + thermal                                   ",
                                          "base + flux harmonics                            ",
                                          "base + cogging (order 18)                        ",
                                          "base + sensor offset, gain, sample delay         ",
                                          "base + PWM delay 1 period                        ",
                                          "base + DC link (rectifier)                       ",
                                          "base + iron loss                                 ",
                                          "base + all of the above (lab-typical-like)       " };
    const long n = argc > 1 ? atol(argv[1]) : 2000000L;
    unsigned char *seq = malloc((size_t)n);
    plant_cfg_t cfg;
    double best[N_CASES], irms = 0.0, sw = 0.0;
    int rep, c;
    if (!seq) {
        return 1;
    }
    build_map();
    for (c = 0; c < N_CASES; c++) {
        const int all = c == N_CASES - 1;
        best[c] = 1e30;
        plant_cfg_default(&cfg);
        if (c >= 1) { /* rig-like sensors and inverter */
            cfg.i_noise_a = 0.05;
            cfg.adc_lsb_a = 40.0 / 4096.0;
            cfg.dead_time_s = 2e-6;
            cfg.v_drop_v = 1.5;
            cfg.i_dt_a = 0.5;
        }
        if (c == 2) {
            cfg.substeps = 2;
        }
        if (c == 3 || all) {
            cfg.map = &bench_map;
        }
        if (c == 4 || all) {
            cfg.thermal_on = 1;
        }
        if (c == 5 || all) {
            cfg.psi5_rel = 0.004;
            cfg.psi7_rel = 0.0014;
        }
        if (c == 6 || all) {
            cfg.cog_nm = 0.1;
            cfg.cog_order_e = 18;
        }
        if (c == 7 || all) {
            cfg.i_offset_a[0] = 0.05;
            cfg.i_gain[1] = 1.01;
            cfg.sample_delay_s = 2e-6;
        }
        if (c == 8) {
            cfg.pwm_delay_periods = 1;
        }
        if (c == 9 || all) {
            cfg.dc_on = 1;
        }
        if (c == 10 || all) {
            cfg.r_fe_ohm = 300.0;
        }
        record(&cfg, seq, n);
        for (rep = 0; rep < 5; rep++) {
            const double ns = replay(&cfg, seq, n, &irms, &sw);
            best[c] = ns < best[c] ? ns : best[c];
        }
    }
    printf("plant_sample + plant_step, paper A IPMSM at 1000 r/min, i_q = 10 A (i_a rms %.1f A, "
           "%.2f leg switchings/period), best of 5 x %ld periods:\n",
           irms, sw, n);
    for (c = 0; c < N_CASES; c++) {
        printf("  %s: %6.1f ns/period\n", names[c], best[c]);
    }
    free(seq);
    return 0;
}
