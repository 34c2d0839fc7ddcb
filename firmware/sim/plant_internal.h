/* Internal to the plant's files (plant.c: configuration, state, truth; plant_mag.h/.c and
 * plant_map.c: magnetics and flux maps; plant_integ.h/.c: the integration; plant_inverter.c: the
 * inverter and PWM off; plant_thermal.c: thermal network and DC link; plant_sensors.c: the
 * measurement chain): constants and the small inline helpers they share. */
#ifndef PLANT_INTERNAL_H
#define PLANT_INTERNAL_H

#include "plant.h"

#include <math.h>
#include <stdint.h>

#define PL_PI        3.14159265358979323846
#define PL_TWO_PI    6.28318530717958647692
#define PL_SQRT3_2   0.86602540378443864676
#define PL_INV_SQRT3 0.57735026918962576451

#if defined(__GNUC__)
#define PL_INLINE static inline __attribute__((always_inline))
#else
#define PL_INLINE static inline
#endif

enum {
    MODE_KNOWN = 0,
    MODE_ONE_BLOCKED = 1,
    MODE_ALL_BLOCKED = 3,
    MODE_UDQ = 4
};

/* ------------------------------------------------------------------ small helpers */

PL_INLINE double sigm(double x)
{
    double x2;
    x = x < 3.0 ? x : 3.0; /* branch-free clamp (minsd/maxsd); the rational is exactly +-1 at +-3 */
    x = x > -3.0 ? x : -3.0;
    x2 = x * x;
    return x * (27.0 + x2) / (27.0 + 9.0 * x2);
}

/* cos and sin of a small angle: Taylor to d^8 / d^9 (error < 2e-15 for |d| < 0.15), libm beyond. */
PL_INLINE void rot_small(double d, double *cd, double *sd)
{
    if (fabs(d) < 0.15) {
        const double d2 = d * d;
        *sd = d * (1.0 - d2 * (1.0 / 6.0) *
                             (1.0 - d2 * (1.0 / 20.0) *
                                        (1.0 - d2 * (1.0 / 42.0) * (1.0 - d2 * (1.0 / 72.0)))));
        *cd = 1.0 -
              d2 * 0.5 *
                  (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0) * (1.0 - d2 * (1.0 / 56.0))));
    } else {
        *sd = sin(d);
        *cd = cos(d);
    }
}

PL_INLINE void phase_currents(double c, double s, double id, double iq, double i3[3])
{
    const double ial = c * id - s * iq, ibe = s * id + c * iq;
    i3[0] = ial;
    i3[1] = -0.5 * ial + PL_SQRT3_2 * ibe;
    i3[2] = -0.5 * ial - PL_SQRT3_2 * ibe;
}

static inline double wrap_2pi(double a)
{
    if (a >= PL_TWO_PI) {
        a -= PL_TWO_PI;
    } else if (a < 0.0) {
        a += PL_TWO_PI;
    }
    if (a >= PL_TWO_PI || a < 0.0) { /* more than one turn per period: only at absurd speeds */
        a = fmod(a, PL_TWO_PI);
        if (a < 0.0) {
            a += PL_TWO_PI;
        }
        if (a >= PL_TWO_PI) {
            a = 0.0;
        }
    }
    return a;
}

/* psi_d, psi_q and d(psi)/d(i) = l[dd, dq, qd, qq]; beyond the grid: linear with the boundary slope */
PL_INLINE void map_eval(const plant_map_t *m, double id, double iq, double *pd, double *pq,
                        double l[4])
{
    double u = (id - m->id0_a) * m->inv_did, v = (iq - m->iq0_a) * m->inv_diq, eu = 0.0, ev = 0.0,
           val[2];
    int j, k, c;
    const double *co;
    j = u < 0.0 ? 0 : (int)u;
    k = v < 0.0 ? 0 : (int)v;
    j = j > m->nd - 2 ? m->nd - 2 : j;
    k = k > m->nq - 2 ? m->nq - 2 : k;
    u -= (double)j;
    v -= (double)k;
    if (u < 0.0) {
        eu = u;
        u = 0.0;
    } else if (u > 1.0) {
        eu = u - 1.0;
        u = 1.0;
    }
    if (v < 0.0) {
        ev = v;
        v = 0.0;
    } else if (v > 1.0) {
        ev = v - 1.0;
        v = 1.0;
    }
    co = &m->coef[k * (PLANT_MAP_MAX_N - 1) + j][0][0];
    /* both components side by side (coefficient pairs [psi_d, psi_q]): the compiler packs them */
    {
        double b[4][2], bv[4][2], fu[2], fv[2];
        int a;
        for (a = 0; a < 4; a++) {
            const double *r = co + 8 * a;
            for (c = 0; c < 2; c++) {
                b[a][c] = r[c] + v * (r[2 + c] + v * (r[4 + c] + v * r[6 + c]));
                bv[a][c] = r[2 + c] + v * (2.0 * r[4 + c] + 3.0 * v * r[6 + c]);
            }
        }
        for (c = 0; c < 2; c++) {
            fu[c] = b[1][c] + u * (2.0 * b[2][c] + 3.0 * u * b[3][c]);
            fv[c] = bv[0][c] + u * (bv[1][c] + u * (bv[2][c] + u * bv[3][c]));
            val[c] =
                b[0][c] + u * (b[1][c] + u * (b[2][c] + u * b[3][c])) + fu[c] * eu + fv[c] * ev;
        }
        l[0] = fu[0] * m->inv_did;
        l[1] = fv[0] * m->inv_diq;
        l[2] = fu[1] * m->inv_did;
        l[3] = fv[1] * m->inv_diq;
    }
    *pd = val[0];
    *pq = val[1];
}

#endif
