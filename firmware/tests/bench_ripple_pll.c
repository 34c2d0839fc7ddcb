/* Ripple PLL at held operating points (not a unit test: make does not run it). From firmware/:
 *   cc -std=c99 -O2 -Icore -Isim -Itests tests/bench_ripple_pll.c core/*.c sim/*.c -lm -o bench_rpll
 *   ./bench_rpll [MAP.txt [a0 a1 a2 a3 b0 b1 b2 b3 c0 c1]]
 * MAP.txt: "nd nq id0 did iq0 diq" then nd*nq psi_d values and nd*nq psi_q values (i_d fastest),
 * the filled grid of a flux map (python -m tools.fluxmap_grid writes it). The Gamma coefficients
 * default to the nominal 1/L_d, 1/L_q. Prints the steady angle error (mean, rms) per point. */
#include <stdio.h>
#include <stdlib.h>

#include "sensorless_loop.h"

static plant_map_t map;
static rerr_tab_t tab;

/* Gamma table from the plant's own map (symmetric part of the inverse incremental inductance) */
static void fill_tab(const plant_t *p, double id0, double did, int nd, double iq0, double diq,
                     int nq)
{
    int j, k;
    tab.nd = (uint16_t)nd;
    tab.nq = (uint16_t)nq;
    tab.id0_a = (float)id0;
    tab.iq0_a = (float)iq0;
    tab.inv_did = (float)(1.0 / did);
    tab.inv_diq = (float)(1.0 / diq);
    for (k = 0; k < nq; k++) {
        for (j = 0; j < nd; j++) {
            plant_mag_t m;
            plant_flux(p, id0 + did * j, iq0 + diq * k, 0.0, &m);
            tab.g[k * nd + j][0] = (float)m.g_dd;
            tab.g[k * nd + j][1] = (float)m.g_qq;
            tab.g[k * nd + j][2] = (float)m.g_dq;
            tab.g[k * nd + j][3] = (float)m.g_qd;
        }
    }
}

static int load_map(const char *path)
{
    static double pd[64 * 64], pq[64 * 64];
    int nd, nq, n, k;
    double id0, did, iq0, diq;
    FILE *f = fopen(path, "r");
    if (f == NULL || fscanf(f, "%d %d %lf %lf %lf %lf", &nd, &nq, &id0, &did, &iq0, &diq) != 6) {
        return 1;
    }
    n = nd * nq;
    for (k = 0; k < n; k++) {
        if (fscanf(f, "%lf", &pd[k]) != 1) {
            return 1;
        }
    }
    for (k = 0; k < n; k++) {
        if (fscanf(f, "%lf", &pq[k]) != 1) {
            return 1;
        }
    }
    fclose(f);
    return plant_map_build(&map, nd, nq, id0, did, iq0, diq, pd, pq) != NULL;
}

int main(int argc, char **argv)
{
    static const double rpm[4] = { 0.0, 15.0, 240.0, 1000.0 };
    static const float iq[3] = { 0.0f, 4.6f, 8.0f }, id[3] = { 0.0f, -0.9f, -2.4f };
    plant_cfg_t pc;
    rpll_cfg_t ec;
    int a, b, k;
    plant_cfg_default(&pc);
    pc.i_noise_a = 0.02;
    pc.adc_lsb_a = 0.0244140625;
    if (argc > 1) {
        if (load_map(argv[1])) {
            fprintf(stderr, "cannot read %s\n", argv[1]);
            return 2;
        }
        pc.map = &map;
    }
    sl_cfg_pll(&ec);
    if (argc == 3) { /* table from the plant's map, spacing argv[2] A */
        plant_t p0;
        double h = atof(argv[2]);
        int nd = (int)(12.0 / h) + 1, nq = (int)(34.0 / h) + 1;
        while (nd * nq > RERR_TAB_MAX) {
            h *= 1.1;
            nd = (int)(12.0 / h) + 1;
            nq = (int)(34.0 / h) + 1;
        }
        plant_init(&p0, &pc);
        fill_tab(&p0, -10.0, h, nd, -17.0, h, nq);
        ec.gamma.tab = &tab;
        printf("table %d x %d, spacing %.2f A\n", nd, nq, h);
    }
    if (argc >= 12) {
        float *g = &ec.gamma.a0;
        for (k = 0; k < 10; k++) {
            g[k] = (float)atof(argv[2 + k]);
        }
    }
    for (a = 0; a < 4; a++) {
        for (b = 0; b < 3; b++) {
            sl_t s;
            double sum = 0.0, sum2 = 0.0;
            const double wm = rpm[a] * 3.14159265358979 / 30.0;
            sl_init(&s, &pc, &ec, 0.7, wm, 0.7f);
            s.i_d_ref_a = id[b];
            s.i_q_ref_a = iq[b];
            for (k = 0; k < 8000; k++) {
                sl_period(&s);
                if (k >= 4000) {
                    const double e = sl_err(&s);
                    sum += e;
                    sum2 += e * e;
                }
            }
            printf("%6.0f r/min  i_q %4.1f A: mean %+.4f rms %.4f rad\n", rpm[a], (double)iq[b],
                   sum / 4000.0, sqrt(sum2 / 4000.0));
        }
    }
    return 0;
}
