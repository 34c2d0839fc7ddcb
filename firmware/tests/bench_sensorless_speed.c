/* The ripple PLL closing the speed loop (not a unit test). From firmware/:
 *   cc -std=c99 -O2 -Icore -Isim -Itests tests/bench_sensorless_speed.c core/*.c sim/*.c -lm -o bench_sl
 *   ./bench_sl [MAP.txt] [bw_rad_s]
 * Paper A's drive on the default rig's inverter and sensors (dead time 2 us, drop 1 V, ADC noise
 * and quantisation, friction), speed PI 1 kHz (kp 1.50, ki 169, b 0.7), MTPA, MPCC on the
 * estimate; at 15, 240 and 1000 r/min a 9 N m load step on for 0.5 s. Prints the steady angle error
 * (rms), the peak through the steps and the speed estimate's error. */
#include <stdio.h>
#include <stdlib.h>

#include "mtpa.h"
#include "sensorless_loop.h"
#include "speed_pi.h"

static plant_map_t map;
static rerr_tab_t tab;

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
    for (k = 0; k < 2 * n; k++) {
        if (fscanf(f, "%lf", k < n ? &pd[k] : &pq[k - n]) != 1) {
            return 1;
        }
    }
    fclose(f);
    return plant_map_build(&map, nd, nq, id0, did, iq0, diq, pd, pq) != NULL;
}

static void fill_tab(const plant_t *p)
{
    int j, k;
    const double h = 1.0730304;
    tab.nd = 12u;
    tab.nq = 33u;
    tab.id0_a = (float)(-11.0 * h);
    tab.iq0_a = (float)(-16.0 * h);
    tab.inv_did = (float)(1.0 / h);
    tab.inv_diq = (float)(1.0 / h);
    for (k = 0; k < 33; k++) {
        for (j = 0; j < 12; j++) {
            plant_mag_t m;
            plant_flux(p, (j - 11) * h, (k - 16) * h, 0.0, &m);
            tab.g[k * 12 + j][0] = (float)m.g_dd;
            tab.g[k * 12 + j][1] = (float)m.g_qq;
            tab.g[k * 12 + j][2] = (float)m.g_dq;
            tab.g[k * 12 + j][3] = (float)m.g_qd;
        }
    }
}

int main(int argc, char **argv)
{
    static const double rpm[3] = { 15.0, 240.0, 1000.0 };
    plant_cfg_t pc;
    rpll_cfg_t ec;
    fw_motor_t mot = { 4u, 0.9f, 5e-3f, 12e-3f, 0.18f, 0.0036f, 15.0f, 1500.0f };
    int a, k;
    plant_cfg_default(&pc);
    pc.i_noise_a = 0.02;
    pc.adc_lsb_a = 0.0244140625;
    pc.dead_time_s = 2e-6;
    pc.v_drop_v = 1.0;
    pc.i_dt_a = 0.5;
    pc.b_visc_nms = 1.2e-3;
    pc.t_coulomb_nm = 0.05;
    sl_cfg_pll(&ec);
    if (argc > 1 && argv[1][0] != '-') {
        plant_t p0;
        if (load_map(argv[1])) {
            return 2;
        }
        pc.map = &map;
        plant_init(&p0, &pc);
        fill_tab(&p0);
        ec.gamma.tab = &tab;
    }
    if (argc > 2) {
        ec.bw_rad_s = (float)atof(argv[2]);
    }
    if (argc > 3) {
        pc.seed = (uint32_t)atoi(argv[3]);
    }
    if (argc > 4) { /* lab-typical's inverter and sensors, by bits */
        const int fx = atoi(argv[4]);
        if (fx & 1) {
            pc.dead_time_s = 2.5e-6;
            pc.v_drop_v = 1.5;
        }
        if (fx & 2) {
            pc.sample_delay_s = 2e-6;
        }
        if (fx & 4) {
            pc.i_gain[1] = 1.01;
            pc.i_gain[2] = 0.995;
        }
        if (fx & 16) { /* an ideal inverter */
            pc.dead_time_s = 0.0;
            pc.v_drop_v = 0.0;
        }
        if (fx & 8) {
            pc.i_offset_a[0] = 0.05;
            pc.i_offset_a[1] = -0.03;
            pc.i_offset_a[2] = 0.02;
        }
    }
    for (a = 0; a < 3; a++) {
        sl_t s;
        speed_pi_t spi;
        speed_pi_cfg_t sc = { 1.50f, 169.0f, 1e-3f, 15.0f };
        if (getenv("SBW") != NULL) { /* speed-loop bandwidth, rad/s */
            const float bw = (float)atof(getenv("SBW"));
            sc.kp_a_per_rad_s = 0.0036f * bw / 1.08f;
            sc.ki_a_per_rad = sc.kp_a_per_rad_s * bw / 4.0f;
        }
        double s2 = 0.0, peak = 0.0, sw = 0.0, sw_n = 0.0, speak = 0.0, lp = 0.0, lpeak = 0.0,
               sw2 = 0.0, tw = 0.0, tw2 = 0.0;
        int n2 = 0;
        const double wm = rpm[a] * 3.14159265358979 / 30.0;
        const int n_on = 10000, n_off = 20000, n_end = 30000; /* 0.5 s, 1.0 s, 1.5 s */
        sl_init(&s, &pc, &ec, 0.3, wm, 0.3f);
        plant_set_mech(&s.p, s.p.theta_m_rad, wm, false);
        s.m.cfg.dead_time_s = (float)pc.dead_time_s > 0.0f ? 2e-6f : 0.0f;
        s.m.cfg.v_drop_v = (float)pc.v_drop_v > 0.0f ? 1.0f : 0.0f;
        s.m.cfg.i_dt_a = 0.5f;
        mpcc_init(&s.m, &s.m.cfg);
        speed_pi_init(&spi, &sc);
        speed_pi_set_ref_weight(&spi, 0.7f);
        speed_pi_preset(&spi, 0.05f, (float)wm, (float)wm);
        for (k = 0; k < n_end; k++) {
            const double load = (k >= n_on && k < n_off) ? 9.0 : 0.0;
            double e;
            if (k % 20 == 0) {
                fw_dq_t r;
                float is = speed_pi_step(&spi, (float)wm, s.w_used / 4.0f);
                mtpa_split(&mot, 1u, is, &r);
                s.i_d_ref_a = r.d;
                s.i_q_ref_a = r.q;
            }
            s.cmd_prev.load_nm = (float)load;
            sl_period(&s);
            e = sl_err(&s);
            if ((k >= 6000 && k < n_on) || (k >= n_end - 4000)) {
                s2 += e * e;
                n2++;
                sw += (double)s.w_used / 4.0 - s.p.omega_m_rad_s;
                sw2 += pow((double)s.w_used / 4.0 - s.p.omega_m_rad_s, 2.0);
                tw += s.p.omega_m_rad_s - wm;
                tw2 += pow(s.p.omega_m_rad_s - wm, 2.0);
                sw_n += 1.0;
            }
            lp += (e - lp) * 0.05; /* 1 ms mean */
            if (k >= 6000 && k < n_on && k % 10 == 0) {
                speak = fabs(e) > speak ? fabs(e) : speak;
            }
            if (k >= n_on) {
                lpeak = fabs(lp) > lpeak ? fabs(lp) : lpeak;
            }
            if (k >= n_on && k % 10 == 0) { /* as the 2 kHz telemetry samples it */
                peak = fabs(e) > peak ? fabs(e) : peak;
            }
        }
        printf("%5.0f r/min: steady rms %.4f rad, peak through the steps %.4f rad, speed est "
               "mean err %+.3f r/min (steady peak %.4f, 1 ms mean peak %.4f)\n"
               "        speed est err rms %.2f r/min, true speed ripple rms %.2f r/min\n",
               rpm[a], sqrt(s2 / n2), peak, sw / sw_n * 30.0 / 3.14159265358979, speak, lpeak,
               sqrt(sw2 / sw_n) * 30.0 / 3.14159265358979,
               sqrt(tw2 / sw_n - pow(tw / sw_n, 2.0)) * 30.0 / 3.14159265358979);
    }
    return 0;
}
