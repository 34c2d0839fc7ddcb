/* Commissioning step: the inverter's distortion voltage against current (docs/commissioning.md).
 *
 * At standstill, a d-axis current staircase in both directions (the q current held at zero, so
 * the rotor feels no torque) gives, at each level, the commanded voltage that holds the current:
 * u_d = R i_d + V g_d(i_abc / i_dt), where g_d is the d component of the per-leg smooth sign
 * sigma (the model the firmware compensates with, mpcc.c) and V the plateau of one leg's
 * distortion (dead time v_dc t_d / Ts plus device drop). For each current band i_dt on a grid,
 * R and V follow by least squares; the band with the smallest residual wins. V fitted on each
 * direction alone shows the repeatability. */
#include "comm.h"
#include "transforms.h"

#include <math.h>

#define INV_SETTLE_S 0.03f
#define INV_MEAS_S   0.04f
#define INV_GRID_N   29u
#define INV_LEVELS   12u /* per direction; COMM_STAIR_MAX = 2 INV_LEVELS */

/* level k of one direction, as a multiple of the nominal band (knee) or of the test current */
static float level_a(const comm_t *c, uint16_t k)
{
    static const float knee[9] = { 0.2f, 0.4f, 0.6f, 0.9f, 1.2f, 1.6f, 2.0f, 2.6f, 3.4f };
    static const float top[3] = { 0.4f, 0.7f, 1.0f };
    return k < 9u ? knee[k] * c->cfg.i_dt_nom_a : top[k - 9u] * c->cfg.i_test_a;
}

static float g_d(const comm_t *c, uint16_t k, float i_dt)
{
    float al, be;
    tf_clarke(comm_smooth_sign(c->st_abc[k][0], i_dt), comm_smooth_sign(c->st_abc[k][1], i_dt),
              comm_smooth_sign(c->st_abc[k][2], i_dt), &al, &be);
    return cosf(c->st_th[k]) * al + sinf(c->st_th[k]) * be;
}

/* The plateau's dead-time part scales with the DC voltage (v_dc t_d / Ts), the device drop does
 * not: with the nominal drop, u - drop g = R i + V_dt (v_dc_k / v_dc_ref) g is linear in R, V_dt. */
static float drop_v(const comm_t *c)
{
    return c->cfg.v_drop_nom_v;
}

static float scale_k(const comm_t *c, uint16_t k)
{
    return c->inv_vdc_v > 1.0f ? c->st_vdc[k] / c->inv_vdc_v : 1.0f;
}

/* least squares of u = R i + V g over points [k0, k1); returns the sum of squared residuals */
static float fit(const comm_t *c, float i_dt, uint16_t k0, uint16_t k1, float *r, float *v)
{
    float sii = 0.0f, sig = 0.0f, sgg = 0.0f, siu = 0.0f, sgu = 0.0f, det, sse = 0.0f;
    uint16_t k;
    for (k = k0; k < k1; k++) {
        const float g0 = g_d(c, k, i_dt), g = g0 * scale_k(c, k), i = c->st_i[k];
        const float u = c->st_u[k] - drop_v(c) * g0;
        sii += i * i;
        sig += i * g;
        sgg += g * g;
        siu += i * u;
        sgu += g * u;
    }
    det = sii * sgg - sig * sig;
    if (!(fabsf(det) > 1e-12f)) {
        *r = 0.0f;
        *v = 0.0f;
        return 1e30f;
    }
    *r = (siu * sgg - sgu * sig) / det;
    *v = (sgu * sii - siu * sig) / det;
    for (k = k0; k < k1; k++) {
        const float g0 = g_d(c, k, i_dt);
        const float e = c->st_u[k] - drop_v(c) * g0 - *r * c->st_i[k] - *v * g0 * scale_k(c, k);
        sse += e * e;
    }
    *v += drop_v(c); /* the plateau at v_dc_ref */
    return sse;
}

/* V alone over [k0, k1), R given */
static float fit_v(const comm_t *c, float i_dt, float r, uint16_t k0, uint16_t k1)
{
    float sgg = 0.0f, sgu = 0.0f;
    uint16_t k;
    for (k = k0; k < k1; k++) {
        const float g0 = g_d(c, k, i_dt), g = g0 * scale_k(c, k);
        sgg += g * g;
        sgu += g * (c->st_u[k] - drop_v(c) * g0 - r * c->st_i[k]);
    }
    return (sgg > 0.0f ? sgu / sgg : 0.0f) + drop_v(c);
}

static void finish(comm_t *c)
{
    const float i_dt0 = c->cfg.i_dt_nom_a;
    float best = 1e30f, r_best = 0.0f, v_best = 0.0f, i_dt_best = i_dt0, vp, vn, rms, v_dc = 0.0f;
    uint16_t g, k;
    c->inv_vdc_v = c->acc[7] / (float)(c->acc_n > 0u ? c->acc_n : 1u);
    for (g = 0u; g < INV_GRID_N; g++) {
        const float i_dt = i_dt0 * (0.2f + 0.1f * (float)g);
        float r, v;
        const float sse = fit(c, i_dt, 0u, c->st_n, &r, &v);
        if (sse < best) {
            best = sse;
            r_best = r;
            v_best = v;
            i_dt_best = i_dt;
        }
    }
    vp = fit_v(c, i_dt_best, r_best, 0u, INV_LEVELS);
    vn = fit_v(c, i_dt_best, r_best, INV_LEVELS, c->st_n);
    rms = sqrtf(best / (float)c->st_n);
    for (k = 0u; k < 4u; k++) {
        c->res.value[k] = 0.0f;
        c->res.spread[k] = 0.0f;
    }
    c->res.value[0] = v_best;
    c->res.value[1] = i_dt_best;
    c->res.value[2] = r_best;
    c->res.value[3] = rms;
    c->res.spread[0] = 0.5f * fabsf(vp - vn);
    v_dc = c->inv_vdc_v;
    c->res.ref[0] = v_dc;
    c->res.ref[1] = c->cfg.i_test_a;
    if (!(v_best >= -0.5f && v_best <= 0.25f * v_dc) ||
        !(r_best >= 0.25f * c->cfg.motor.r_s_ohm && r_best <= 4.0f * c->cfg.motor.r_s_ohm) ||
        !(rms <= 0.5f + 0.05f * fabsf(v_best))) {
        comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
        return;
    }
    if (!(fabsf(vp - vn) <= 0.1f * v_best + 0.2f)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_NOT_REPEATABLE);
        return;
    }
    if (v_best < 0.3f) { /* no measurable distortion (an ideal inverter): no model, no band */
        v_best = 0.0f;
        i_dt_best = i_dt0;
        c->res.value[0] = 0.0f;
        c->res.value[1] = i_dt0;
    }
    c->inv_v = v_best;
    c->inv_i_dt_a = i_dt_best;
    c->have_inv = true;
    c->r_ohm = r_best;
    comm_finish_step(c);
}

void comm_inverter_step(comm_t *c, comm_out_t *out)
{
    const uint16_t k = c->st_k;
    const float sign = k < INV_LEVELS ? 1.0f : -1.0f;
    const float ref = sign * level_a(c, (uint16_t)(k < INV_LEVELS ? k : k - INV_LEVELS));
    float id, iq;
    c->i_max_step = 1.5f * c->cfg.i_test_a + 1.0f;
    if (comm_over_current(c)) {
        return;
    }
    comm_current(c, c->c_rot, c->s_rot, ref, 0.0f, &id, &iq, out);
    c->acc[7] += c->v_dc;
    c->acc_n++;
    if (c->phase == 0u) {
        if (comm_elapsed(c, INV_SETTLE_S)) {
            c->phase = 1u;
            c->t = 0u;
            c->acc[0] = c->acc[1] = c->acc[2] = c->acc[3] = c->acc[4] = 0.0f;
            c->acc[5] = c->acc[6] = 0.0f;
            c->st_vdc[k] = 0.0f;
        }
        return;
    }
    c->acc[0] += id;
    c->acc[1] += c->u_d;
    c->acc[2] += c->ia;
    c->acc[3] += c->ib;
    c->acc[4] += c->ic;
    c->st_vdc[k] += c->v_dc;
    c->acc[5] += c->c_rot;
    c->acc[6] += c->s_rot;
    if (!comm_elapsed(c, INV_MEAS_S)) {
        return;
    }
    {
        const float n = (float)c->t + 1.0f; /* samples in this window */
        c->st_i[k] = c->acc[0] / n;
        c->st_u[k] = c->acc[1] / n;
        c->st_abc[k][0] = c->acc[2] / n;
        c->st_abc[k][1] = c->acc[3] / n;
        c->st_abc[k][2] = c->acc[4] / n;
        c->st_th[k] = atan2f(c->acc[6], c->acc[5]);
        c->st_vdc[k] /= n;
        c->st_n = (uint16_t)(k + 1u);
        c->st_k = (uint16_t)(k + 1u);
    }
    c->phase = 0u;
    c->t = 0u;
    if (c->st_k >= 2u * INV_LEVELS) {
        finish(c);
    }
}
