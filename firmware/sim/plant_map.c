/* Flux maps for saturation: bicubic Hermite patches over a regular (i_d, i_q) grid (docs/rigs.md). */
#include "plant_internal.h"

#include <stddef.h>

/* ------------------------------------------------------------------ flux map (saturation) */

/* bicubic Hermite basis: p(t) = M [f(0), f(1), f'(0), f'(1)] gives the power coefficients */
static const double HM[4][4] = { { 1.0, 0.0, 0.0, 0.0 },
                                 { 0.0, 0.0, 1.0, 0.0 },
                                 { -3.0, 3.0, -2.0, -1.0 },
                                 { 2.0, -2.0, 1.0, 1.0 } };

/* node derivative along one grid line by finite differences (central inside, one-sided at the ends) */
static double fd(const double *f, int j, int n, int stride)
{
    if (j == 0) {
        return f[stride] - f[0];
    }
    if (j == n - 1) {
        return f[(size_t)j * (size_t)stride] - f[(size_t)(j - 1) * (size_t)stride];
    }
    return 0.5 * (f[(size_t)(j + 1) * (size_t)stride] - f[(size_t)(j - 1) * (size_t)stride]);
}

const char *plant_map_build(plant_map_t *m, int nd, int nq, double id0_a, double did_a,
                            double iq0_a, double diq_a, const double *psi_d_wb,
                            const double *psi_q_wb)
{
    static double ft[2][PLANT_MAP_MAX_N * PLANT_MAP_MAX_N],
        fv[2][PLANT_MAP_MAX_N * PLANT_MAP_MAX_N], ftv[2][PLANT_MAP_MAX_N * PLANT_MAP_MAX_N];
    const double *f[2];
    int c, j, k, a, b;
    if (nd < 2 || nq < 2 || nd > PLANT_MAP_MAX_N || nq > PLANT_MAP_MAX_N)
        return "flux map: 2 to 64 nodes per axis";
    if (!(did_a > 0.0) || !(diq_a > 0.0))
        return "flux map: node spacing must be > 0";
    if (psi_d_wb == NULL || psi_q_wb == NULL)
        return "flux map: no data";
    for (j = 0; j < nd * nq; j++) {
        if (!(fabs(psi_d_wb[j]) < 1e6) || !(fabs(psi_q_wb[j]) < 1e6))
            return "flux map: value not finite";
    }
    m->nd = nd;
    m->nq = nq;
    m->id0_a = id0_a;
    m->iq0_a = iq0_a;
    m->did_a = did_a;
    m->diq_a = diq_a;
    m->inv_did = 1.0 / did_a;
    m->inv_diq = 1.0 / diq_a;
    f[0] = psi_d_wb;
    f[1] = psi_q_wb;
    /* node derivatives in cell units (per node spacing) */
    for (c = 0; c < 2; c++) {
        for (k = 0; k < nq; k++) {
            for (j = 0; j < nd; j++) {
                ft[c][k * nd + j] = fd(f[c] + k * nd, j, nd, 1);
                fv[c][k * nd + j] = fd(f[c] + j, k, nq, nd);
            }
        }
        for (k = 0; k < nq; k++) {
            for (j = 0; j < nd; j++) {
                ftv[c][k * nd + j] = fd(fv[c] + k * nd, j, nd, 1);
            }
        }
    }
    for (c = 0; c < 2; c++) {
        for (k = 0; k < nq - 1; k++) {
            for (j = 0; j < nd - 1; j++) {
                /* F[a][b]: a = value/derivative in t at t = 0, 1; b likewise in v */
                double F[4][4], T[4][4];
                int n00 = k * nd + j, n10 = n00 + 1, n01 = n00 + nd, n11 = n01 + 1;
                double *co = &m->coef[k * (PLANT_MAP_MAX_N - 1) + j][0][0];
                F[0][0] = f[c][n00];
                F[0][1] = f[c][n01];
                F[0][2] = fv[c][n00];
                F[0][3] = fv[c][n01];
                F[1][0] = f[c][n10];
                F[1][1] = f[c][n11];
                F[1][2] = fv[c][n10];
                F[1][3] = fv[c][n11];
                F[2][0] = ft[c][n00];
                F[2][1] = ft[c][n01];
                F[2][2] = ftv[c][n00];
                F[2][3] = ftv[c][n01];
                F[3][0] = ft[c][n10];
                F[3][1] = ft[c][n11];
                F[3][2] = ftv[c][n10];
                F[3][3] = ftv[c][n11];
                for (a = 0; a < 4; a++) { /* T = HM F */
                    for (b = 0; b < 4; b++) {
                        T[a][b] = HM[a][0] * F[0][b] + HM[a][1] * F[1][b] + HM[a][2] * F[2][b] +
                                  HM[a][3] * F[3][b];
                    }
                }
                for (a = 0; a < 4; a++) { /* coefficient of t^a v^b: (HM F HM^T)[a][b] */
                    for (b = 0; b < 4; b++) {
                        co[(a * 4 + b) * 2 + c] = T[a][0] * HM[b][0] + T[a][1] * HM[b][1] +
                                                  T[a][2] * HM[b][2] + T[a][3] * HM[b][3];
                    }
                }
            }
        }
    }
    m->psi_f_wb = 0.0;
    {
        double pq, l[4];
        plant_map_eval(m, 0.0, 0.0, &m->psi_f_wb, &pq, l);
    }
    return NULL;
}

void plant_map_eval(const plant_map_t *m, double i_d_a, double i_q_a, double *psi_d_wb,
                    double *psi_q_wb, double l[4])
{
    map_eval(m, i_d_a, i_q_a, psi_d_wb, psi_q_wb, l);
}
