/* The dq plant with paper A's motor and drive that the MPCC unit tests close the loop on
 * (test_mpcc.c): exact per-period integration with the inverter's dead time and device drop. */
#ifndef MPCC_PLANT_H
#define MPCC_PLANT_H

#include <math.h>

#include "mpcc.h"
#include "transforms.h"

/* Paper A's motor and drive. */
#define R_OHM  0.9
#define LD_H   0.005
#define LQ_H   0.012
#define PSI_WB 0.18
#define POLES  4
#define VDC_V  540.0
#define TS_S   50e-6
#define PI_D   3.14159265358979323846

/* ------------------------------------------------------------------ plant
 * Continuous dq model integrated with fine Euler sub-steps (the "exact" plant the Euler
 * predictor is compared against). The inverter holds a switch state for a whole period; the
 * state chosen by the controller at k is applied from k+1 on (one-period computation delay).
 * Optional switch-level dead time: after a leg changes state both its switches are off for
 * td_s, and the pole voltage follows the current sign (i > 0: 0, i < 0: v_dc); plus a device
 * drop -v_drop sign(i). */
typedef struct {
    double i_d, i_q, theta, w; /* electrical */
    double r, l_d, l_q, psi, vdc;
    double td_s, v_drop;
    int sw;                /* state applied during the current period */
    double sum_id, sum_iq; /* time integral of the currents over the last period / Ts */
    double sum_ud, sum_uq; /* average dq voltage over the last period (rotating frame) */
} plant_t;

#define N_SUB 100

static inline void plant_init(plant_t *p, double w)
{
    p->i_d = 0.0;
    p->i_q = 0.0;
    p->theta = 0.3;
    p->w = w;
    p->r = R_OHM;
    p->l_d = LD_H;
    p->l_q = LQ_H;
    p->psi = PSI_WB;
    p->vdc = VDC_V;
    p->td_s = 0.0;
    p->v_drop = 0.0;
    p->sw = 0;
    p->sum_id = 0.0;
    p->sum_iq = 0.0;
}

static inline double sgn(double x)
{
    return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0);
}

/* One control period with switch state sw_new applied from its start. */
static inline void plant_period(plant_t *p, int sw_new)
{
    const double h = TS_S / N_SUB;
    int n, x;
    p->sum_id = 0.0;
    p->sum_iq = 0.0;
    p->sum_ud = 0.0;
    p->sum_uq = 0.0;
    for (n = 0; n < N_SUB; n++) {
        const double t = (n + 0.5) * h;
        const double th = p->theta + p->w * t;
        const double c = cos(th), s = sin(th);
        /* phase currents */
        const double ia = c * p->i_d - s * p->i_q;
        const double ib_ = s * p->i_d + c * p->i_q;
        double iph[3], v[3], ua, ub, ud, uq, did, diq;
        iph[0] = ia;
        iph[1] = -0.5 * ia + 0.8660254037844386 * ib_;
        iph[2] = -0.5 * ia - 0.8660254037844386 * ib_;
        for (x = 0; x < 3; x++) {
            const int on_new = (sw_new >> x) & 1;
            const int on_old = (p->sw >> x) & 1;
            if (on_new != on_old && t < p->td_s) {
                v[x] = iph[x] > 0.0 ? 0.0 : (iph[x] < 0.0 ? p->vdc : on_old * p->vdc);
            } else {
                v[x] = on_new * p->vdc;
            }
            v[x] -= p->v_drop * sgn(iph[x]);
        }
        ua = (2.0 * v[0] - v[1] - v[2]) / 3.0;
        ub = (v[1] - v[2]) / sqrt(3.0);
        ud = c * ua + s * ub;
        uq = -s * ua + c * ub;
        did = (ud - p->r * p->i_d + p->w * p->l_q * p->i_q) / p->l_d;
        diq = (uq - p->r * p->i_q - p->w * p->l_d * p->i_d - p->w * p->psi) / p->l_q;
        p->sum_ud += ud / N_SUB;
        p->sum_uq += uq / N_SUB;
        p->sum_id += (p->i_d + 0.5 * h * did) / N_SUB;
        p->sum_iq += (p->i_q + 0.5 * h * diq) / N_SUB;
        p->i_d += h * did;
        p->i_q += h * diq;
    }
    p->theta += p->w * TS_S;
    p->theta = fmod(p->theta, 2.0 * PI_D);
    p->sw = sw_new;
}

static inline void fill_in(mpcc_in_t *in, const plant_t *p, float id_ref, float iq_ref)
{
    in->i_d_a = (float)p->i_d;
    in->i_q_a = (float)p->i_q;
    in->i_d_ref_a = id_ref;
    in->i_q_ref_a = iq_ref;
    in->theta_e_rad = (float)p->theta;
    in->omega_e_rad_s = (float)p->w;
    in->v_dc_v = (float)p->vdc;
    in->r_s_ohm = (float)R_OHM;
    in->l_d_h = (float)LD_H;
    in->l_q_h = (float)LQ_H;
    in->psi_f_wb = (float)PSI_WB;
}

typedef struct {
    double mean_ed, mean_eq, rms_ed, rms_eq, sw_per_s;
    double avg_ed, avg_eq; /* error of the time-averaged (not sampled) current */
} track_t;

/* Run MPCC on the plant at a fixed electrical speed; statistics after a 10 ms settling time. */
static inline track_t run_track(const mpcc_cfg_t *cfg, double w, double td_s, double v_drop,
                                float id_ref, float iq_ref, double t_end)
{
    mpcc_t m;
    mpcc_in_t in;
    mpcc_out_t out;
    plant_t p;
    track_t r = { 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0 };
    long k, n_k = (long)(t_end / TS_S + 0.5), n_stat = 0, n_sw = 0;
    int pending = 0;
    mpcc_init(&m, cfg);
    plant_init(&p, w);
    p.td_s = td_s;
    p.v_drop = v_drop;
    /* start near the operating point */
    p.i_d = id_ref;
    p.i_q = iq_ref;
    for (k = 0; k < n_k; k++) {
        fill_in(&in, &p, id_ref, iq_ref);
        mpcc_step(&m, &in, &out);
        if (k * TS_S >= 0.01) {
            const double ed = id_ref - p.i_d, eq = iq_ref - p.i_q;
            r.mean_ed += ed;
            r.mean_eq += eq;
            r.rms_ed += ed * ed;
            r.rms_eq += eq * eq;
            n_stat++;
            if (out.s_abc_next != (uint16_t)pending) {
                n_sw += 1;
            }
        }
        plant_period(&p, pending);
        pending = out.s_abc_next;
        if (k * TS_S >= 0.01) {
            r.avg_ed += id_ref - p.sum_id;
            r.avg_eq += iq_ref - p.sum_iq;
        }
    }
    r.avg_ed /= (double)n_stat;
    r.avg_eq /= (double)n_stat;
    r.mean_ed /= (double)n_stat;
    r.mean_eq /= (double)n_stat;
    r.rms_ed = sqrt(r.rms_ed / (double)n_stat);
    r.rms_eq = sqrt(r.rms_eq / (double)n_stat);
    r.sw_per_s = (double)n_sw / ((double)n_stat * TS_S);
    return r;
}

static inline mpcc_cfg_t cfg_default(void)
{
    mpcc_cfg_t c;
    mpcc_cfg_default(&c);
    c.ts_s = (float)TS_S;
    return c;
}

#endif
