/* Commissioning step: the inverter's distortion voltage against current (docs/commissioning.md).
 *
 * At standstill, a d-axis current staircase in both directions (the q current held at zero, so
 * the rotor feels no torque) gives, at each level, the commanded voltage that holds the current.
 * Each leg adds its device drop V_drop sigma(i / i_dt) in every period and its dead time
 * V_dt sigma(i / i_dt) (V_dt = v_dc t_d / Ts) only in a period in which it switches (sigma: the
 * smooth sign the firmware compensates with, mpcc.c). The staircase runs twice: with space-vector
 * PWM (every leg switches, the two add up to one plateau) and with discontinuous PWM (the lowest
 * leg clamped to the lower rail: no edges, only its drop), which tells them apart:
 * u_d = R i_d + V_dt (v_dc_k / v_dc_ref) g_sw + V_drop g_all, g the d components of the legs'
 * signs (g_sw: weighted by the share of periods each leg switched). For each current band i_dt on
 * a grid, R, V_dt and V_drop follow by least squares; the band with the smallest residual wins.
 * The fit on each direction alone shows the repeatability. */
#include "comm.h"
#include "transforms.h"

#include <math.h>

#define INV_SETTLE_S 0.03f
#define INV_MEAS_S   0.04f
#define INV_GRID_N   29u
#define INV_LEVELS   12u /* per direction and PWM; COMM_STAIR_MAX = 4 INV_LEVELS */

/* level k of the staircase (INV_LEVELS per direction, positive first; SVPWM, then clamped PWM),
 * as a multiple of the nominal band (knee) or of the test current */
static float level_a(const comm_t *c, uint16_t k)
{
    static const float knee[9] = { 0.2f, 0.4f, 0.6f, 0.9f, 1.2f, 1.6f, 2.0f, 2.6f, 3.4f };
    static const float top[3] = { 0.4f, 0.7f, 1.0f };
    const uint16_t j = (uint16_t)(k % INV_LEVELS);
    const float a = j < 9u ? knee[j] * c->cfg.i_dt_nom_a : top[j - 9u] * c->cfg.i_test_a;
    return ((k / INV_LEVELS) & 1u) == 0u ? a : -a;
}

/* d components of the legs' smooth signs at point k: all legs (g_all), and weighted by the share
 * of periods in which each switched (g_sw) */
static void g_d(const comm_t *c, uint16_t k, float i_dt, float *g_all, float *g_sw)
{
    float sg[3], al, be, cs, sn;
    uint16_t x;
    for (x = 0u; x < 3u; x++) {
        sg[x] = comm_smooth_sign(c->st_abc[k][x], i_dt);
    }
    cs = cosf(c->st_th[k]);
    sn = sinf(c->st_th[k]);
    tf_clarke(sg[0], sg[1], sg[2], &al, &be);
    *g_all = cs * al + sn * be;
    tf_clarke(sg[0] * c->st_sw[k][0], sg[1] * c->st_sw[k][1], sg[2] * c->st_sw[k][2], &al, &be);
    *g_sw = cs * al + sn * be;
}

/* The dead time's part scales with the DC voltage (v_dc t_d / Ts), the device drop does not. */
static float scale_k(const comm_t *c, uint16_t k)
{
    return c->inv_vdc_v > 1.0f ? c->st_vdc[k] / c->inv_vdc_v : 1.0f;
}

/* a point of direction dir (+1, -1; 0: both) */
static bool in_dir(const comm_t *c, uint16_t k, int16_t dir)
{
    return dir == 0 || (dir > 0 ? c->st_i[k] > 0.0f : c->st_i[k] < 0.0f);
}

typedef struct {
    float r, v_dt, v_drop; /* v_dt at the reference DC voltage */
} inv_fit_t;

/* the regressors of point k: i, the switching legs' signs scaled by the DC voltage, all legs'
 * signs (the fourth unused) */
static void regressors(const comm_t *c, uint16_t k, float i_dt, float x[COMM_REG_N])
{
    float g_all, g_sw;
    g_d(c, k, i_dt, &g_all, &g_sw);
    x[0] = c->st_i[k];
    x[1] = g_sw * scale_k(c, k);
    x[2] = g_all;
    x[3] = 0.0f;
}

/* least squares of u = R i + V_dt s g_sw + V_drop g_all over the points of direction dir;
 * returns the sum of squared residuals (1e30 when singular) */
static float fit(const comm_t *c, float i_dt, int16_t dir, inv_fit_t *f)
{
    comm_reg_t reg;
    float x[COMM_REG_N], a[COMM_REG_N], sse = 0.0f;
    uint16_t k;
    comm_reg_reset(&reg);
    for (k = 0u; k < c->st_n; k++) {
        if (in_dir(c, k, dir)) {
            regressors(c, k, i_dt, x);
            comm_reg_add(&reg, x, c->st_u[k]);
        }
    }
    if (!comm_reg_solve(&reg, 3u, a)) {
        f->r = f->v_dt = f->v_drop = 0.0f;
        return 1e30f;
    }
    f->r = a[0];
    f->v_dt = a[1];
    f->v_drop = a[2];
    for (k = 0u; k < c->st_n; k++) {
        if (in_dir(c, k, dir)) {
            float e;
            regressors(c, k, i_dt, x);
            e = c->st_u[k] - f->r * x[0] - f->v_dt * x[1] - f->v_drop * x[2];
            sse += e * e;
        }
    }
    return sse;
}

static void finish(comm_t *c)
{
    const float i_dt0 = c->cfg.i_dt_nom_a;
    float best = 1e30f, i_dt_best = i_dt0, rms, v_dc, v_best, drop;
    inv_fit_t fb = { 0.0f, 0.0f, 0.0f }, fp, fn;
    uint16_t g, k;
    c->inv_vdc_v = c->acc[7] / (float)(c->acc_n > 0u ? c->acc_n : 1u);
    for (g = 0u; g < INV_GRID_N; g++) {
        const float i_dt = i_dt0 * (0.2f + 0.1f * (float)g);
        inv_fit_t f;
        const float sse = fit(c, i_dt, 0, &f);
        if (sse < best) {
            best = sse;
            fb = f;
            i_dt_best = i_dt;
        }
    }
    (void)fit(c, i_dt_best, 1, &fp);
    (void)fit(c, i_dt_best, -1, &fn);
    rms = sqrtf(best / (float)c->st_n);
    v_best = fb.v_dt + fb.v_drop; /* one leg's plateau at v_dc_ref (both parts) */
    drop = fb.v_drop;
    for (k = 0u; k < COMM_RES_N; k++) {
        c->res.value[k] = 0.0f;
        c->res.spread[k] = 0.0f;
    }
    c->res.value[0] = v_best;
    c->res.value[1] = i_dt_best;
    c->res.value[2] = fb.r;
    c->res.value[3] = drop;
    c->res.value[4] = rms;
    c->res.spread[0] = 0.5f * fabsf((fp.v_dt + fp.v_drop) - (fn.v_dt + fn.v_drop));
    c->res.spread[3] = 0.5f * fabsf(fp.v_drop - fn.v_drop);
    v_dc = c->inv_vdc_v;
    c->res.ref[0] = v_dc;
    c->res.ref[1] = c->cfg.i_test_a;
    if (!(v_best >= -0.5f && v_best <= 0.25f * v_dc) ||
        !(fb.r >= 0.25f * c->cfg.motor.r_s_ohm && fb.r <= 4.0f * c->cfg.motor.r_s_ohm) ||
        !(rms <= 0.5f + 0.05f * fabsf(v_best)) || !(drop >= -0.5f && drop <= v_best + 0.5f)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
        return;
    }
    /* the drop is told from the dead time's part by its current dependence: the fit's error
     * in it scales with the whole plateau too (a 3 us dead time's 35 V against a 0.9 V drop:
     * the two directions' drops 0.4 V apart), hence the 2 % of v_best */
    if (!(2.0f * c->res.spread[0] <= 0.1f * v_best + 0.2f) ||
        !(2.0f * c->res.spread[3] <= 0.2f * fabsf(drop) + 0.2f + 0.02f * v_best)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_NOT_REPEATABLE);
        return;
    }
    if (v_best < 0.3f) { /* no measurable distortion (an ideal inverter): no model, no band */
        v_best = 0.0f;
        drop = 0.0f;
        i_dt_best = i_dt0;
        c->res.value[0] = 0.0f;
        c->res.value[1] = i_dt0;
    }
    /* the device drop within [0, plateau]: the split the firmware's model can hold */
    drop = drop < 0.0f ? 0.0f : (drop > v_best ? v_best : drop);
    c->res.value[3] = drop;
    c->inv_v = v_best;
    c->inv_drop_v = drop;
    c->inv_i_dt_a = i_dt_best;
    c->have_inv = true;
    c->r_ohm = fb.r;
    comm_finish_step(c);
}

void comm_inverter_step(comm_t *c, comm_out_t *out)
{
    const uint16_t k = c->st_k;
    const float ref = level_a(c, k);
    float id, iq;
    uint16_t x;
    c->i_max_step = 1.5f * c->cfg.i_test_a + 1.0f;
    if (comm_over_current(c)) {
        return;
    }
    c->dpwm_lo = k >= 2u * INV_LEVELS;
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
            for (x = 0u; x < 3u; x++) {
                c->st_sw[k][x] = 0.0f;
            }
        }
        return;
    }
    for (x = 0u; x < 3u; x++) { /* a leg switches in a period unless its duty sits on a rail */
        c->st_sw[k][x] += (out->duty[x] > 0.0f && out->duty[x] < 1.0f) ? 1.0f : 0.0f;
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
        for (x = 0u; x < 3u; x++) {
            c->st_sw[k][x] /= n;
        }
        c->st_n = (uint16_t)(k + 1u);
        c->st_k = (uint16_t)(k + 1u);
    }
    c->phase = 0u;
    c->t = 0u;
    if (c->st_k >= 4u * INV_LEVELS) {
        finish(c);
    }
}
