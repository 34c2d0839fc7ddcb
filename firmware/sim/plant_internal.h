/* Internal to the plant's files (plant.c: configuration, state, truth; plant_mag.h/.c and
 * plant_map.c: magnetics and flux maps; plant_integ.h/.c: the integration; plant_inverter.c: the
 * inverter and PWM off; plant_thermal.c: thermal network and DC link; plant_sensors.c: the
 * measurement chain): constants and the small inline helpers they share. */
#ifndef PLANT_INTERNAL_H
#define PLANT_INTERNAL_H

#include "plant.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

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
    int j, k;
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
#if defined(__GNUC__) && !defined(PL_MAP_SCALAR)
    /* both components side by side (coefficient pairs [psi_d, psi_q]) in one 2-wide vector: each
     * lane does exactly the scalar code's operations in its order (the #else branch), so the
     * values are bit for bit the same, in half the instructions */
    {
        typedef double v2_t __attribute__((vector_size(16)));
        const double v3 = 3.0 * v, u3 = 3.0 * u;
        const v2_t vv = { v, v }, vv3 = { v3, v3 }, uu = { u, u }, uu3 = { u3, u3 },
                   two = { 2.0, 2.0 }, euv = { eu, eu }, evv = { ev, ev };
        v2_t b[4], bv[4], r0, r2, r4, r6, fu, fv, vl;
        int a;
        for (a = 0; a < 4; a++) {
            const double *r = co + 8 * a;
            memcpy(&r0, r, sizeof r0);
            memcpy(&r2, r + 2, sizeof r2);
            memcpy(&r4, r + 4, sizeof r4);
            memcpy(&r6, r + 6, sizeof r6);
            b[a] = r0 + vv * (r2 + vv * (r4 + vv * r6));
            bv[a] = r2 + vv * (two * r4 + vv3 * r6);
        }
        fu = b[1] + uu * (two * b[2] + uu3 * b[3]);
        fv = bv[0] + uu * (bv[1] + uu * (bv[2] + uu * bv[3]));
        vl = b[0] + uu * (b[1] + uu * (b[2] + uu * b[3])) + fu * euv + fv * evv;
        val[0] = vl[0];
        val[1] = vl[1];
        l[0] = fu[0] * m->inv_did;
        l[1] = fv[0] * m->inv_diq;
        l[2] = fu[1] * m->inv_did;
        l[3] = fv[1] * m->inv_diq;
    }
#else
    {
        double b[4][2], bv[4][2], fu[2], fv[2];
        int a, c;
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
#endif
    *pd = val[0];
    *pq = val[1];
}

#endif
