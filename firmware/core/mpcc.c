/* Finite-control-set MPCC (paper A (2)-(5)) with one-period delay compensation and an optional
 * dead-time/device-drop model. See mpcc.h and docs/control.md. C28x-safe: float only, one
 * sinf/cosf pair per call, two divisions only when the predictor inductances change. */
#include "mpcc.h"

#include <math.h>
#include "transforms.h"

/* alpha/beta voltage of each code (code = s_a | s_b << 1 | s_c << 2), per volt of v_dc,
 * amplitude-invariant: u_alpha = (2 s_a - s_b - s_c)/3, u_beta = (s_b - s_c)/sqrt(3). */
static const float k_vec_alpha[8] = { 0.0f,         2.0f / 3.0f, -1.0f / 3.0f, 1.0f / 3.0f,
                                      -1.0f / 3.0f, 1.0f / 3.0f, -2.0f / 3.0f, 0.0f };
static const float k_vec_beta[8] = {
    0.0f, 0.0f, TF_INV_SQRT3_F, TF_INV_SQRT3_F, -TF_INV_SQRT3_F, -TF_INV_SQRT3_F, 0.0f, 0.0f
};

#define MPCC_L_MIN_H 1.0e-7f

void mpcc_vector(uint16_t code, float *u_alpha_per_vdc, float *u_beta_per_vdc)
{
    uint16_t c = (uint16_t)(code & 7u);
    *u_alpha_per_vdc = k_vec_alpha[c];
    *u_beta_per_vdc = k_vec_beta[c];
}

void mpcc_cfg_default(mpcc_cfg_t *cfg)
{
    cfg->ts_s = 50.0e-6f;
    cfg->rho = 1.0f;
    cfg->dead_time_s = 0.0f;
    cfg->v_drop_v = 0.0f;
    cfg->i_dt_a = 0.0f;
    cfg->cand_set = MPCC_CAND_ALL8;
    cfg->dt_model = MPCC_DT_SWITCHING;
    cfg->delay_comp = MPCC_DELAY_COMP_ON;
    cfg->k_int_rad_s = MPCC_K_INT_DEFAULT_RAD_S;
    cfg->int_max_a = MPCC_INT_MAX_DEFAULT_A;
}

void mpcc_init(mpcc_t *m, const mpcc_cfg_t *cfg)
{
    m->cfg = *cfg;
    m->inv_i_dt = (m->cfg.i_dt_a > 0.0f && m->cfg.i_dt_a < 1.0e6f) ? 1.0f / m->cfg.i_dt_a : 0.0f;
    if (!(m->cfg.ts_s > 0.0f)) {
        m->cfg.ts_s = 50.0e-6f;
    }
    if (!(m->cfg.rho >= 0.0f)) {
        m->cfg.rho = 1.0f;
    }
    if (!(m->cfg.dead_time_s >= 0.0f)) {
        m->cfg.dead_time_s = 0.0f;
    }
    if (!(m->cfg.v_drop_v >= 0.0f)) {
        m->cfg.v_drop_v = 0.0f;
    }
    if (m->cfg.cand_set != MPCC_CAND_ADJACENT) {
        m->cfg.cand_set = MPCC_CAND_ALL8;
    }
    if (m->cfg.dt_model != MPCC_DT_AVERAGE) {
        m->cfg.dt_model = MPCC_DT_SWITCHING;
    }
    if (m->cfg.delay_comp != MPCC_DELAY_COMP_OFF) {
        m->cfg.delay_comp = MPCC_DELAY_COMP_ON;
    }
    if (!(m->cfg.k_int_rad_s > 0.0f) || !(m->cfg.k_int_rad_s * m->cfg.ts_s < 0.5f)) {
        m->cfg.k_int_rad_s = 0.0f;
    }
    if (!(m->cfg.int_max_a >= 0.0f) || !(m->cfg.int_max_a < 1.0e6f)) {
        m->cfg.int_max_a = 0.0f;
    }
    m->l_d_cached_h = 0.0f;
    m->l_q_cached_h = 0.0f;
    m->inv_l_d = 0.0f;
    m->inv_l_q = 0.0f;
    mpcc_reset(m);
}

void mpcc_reset(mpcc_t *m)
{
    m->sw_prev = 0u;
    m->sw_prev2 = 0u;
    m->int_d_a = 0.0f;
    m->int_q_a = 0.0f;
    m->ext_applied = false;
    m->ext_u_alpha_v = 0.0f;
    m->ext_u_beta_v = 0.0f;
}

void mpcc_take_over(mpcc_t *m, float u_alpha_v, float u_beta_v)
{
    mpcc_reset(m);
    if (u_alpha_v == u_alpha_v && u_beta_v == u_beta_v) {
        m->ext_applied = true;
        m->ext_u_alpha_v = u_alpha_v;
        m->ext_u_beta_v = u_beta_v;
    }
}

static float clampf(float x, float lim)
{
    return (x > lim) ? lim : ((x < -lim) ? -lim : x);
}

static float sgn3(float x)
{
    return (x > 0.0f) ? 1.0f : ((x < 0.0f) ? -1.0f : 0.0f);
}

/* Smooth sign of the inverter's distortion: x (27 + x^2) / (27 + 9 x^2) for |x| < 3, sign beyond
 * (C1, within 0.025 of tanh): a small current cannot swing a leg within the dead time. With
 * inv_i_dt = 0 it is the ideal sign. */
static float smooth_sign(float i, float inv_i_dt)
{
    float x, x2;
    if (!(inv_i_dt > 0.0f)) {
        return sgn3(i);
    }
    x = i * inv_i_dt;
    if (x >= 3.0f) {
        return 1.0f;
    }
    if (x <= -3.0f) {
        return -1.0f;
    }
    x2 = x * x;
    return x * (27.0f + x2) / (27.0f + 9.0f * x2);
}

static uint16_t n_changes(uint16_t a, uint16_t b)
{
    uint16_t x = (uint16_t)((a ^ b) & 7u);
    return (uint16_t)((x & 1u) + ((x >> 1) & 1u) + ((x >> 2) & 1u));
}

/* Effective pole voltage of each leg for both switch positions during one period, as the
 * firmware models the inverter: v[x][s] with x = leg (a, b, c), s = commanded upper switch.
 * prev: the state before the period (for the switching model), i_abc: phase currents whose sign
 * decides the distortion. Ideal: v = s v_dc. */
static void leg_voltages(const mpcc_t *m, float v_dc_v, uint16_t prev, const float i_abc[3],
                         float v[3][2])
{
    uint16_t x;
    const float v_edge = v_dc_v * m->cfg.dead_time_s / m->cfg.ts_s;
    const float inv_i_dt = m->inv_i_dt;
    for (x = 0u; x < 3u; x++) {
        const float sg = smooth_sign(i_abc[x], inv_i_dt);
        float d0, d1;
        if (m->cfg.dt_model == MPCC_DT_SWITCHING) {
            const uint16_t was_on = (uint16_t)(((uint16_t)(prev >> x)) & 1u);
            /* turned on (0 -> 1) with i > 0: the lower diode carries the dead time, -v_dc Td;
             * turned off (1 -> 0) with i < 0: the upper diode carries it, +v_dc Td; weighted by
             * (1 +- sigma)/2 near the current's zero crossing. */
            d1 = (was_on == 0u) ? -v_edge * 0.5f * (1.0f + sg) : 0.0f;
            d0 = (was_on == 1u) ? v_edge * 0.5f * (1.0f - sg) : 0.0f;
            d1 -= m->cfg.v_drop_v * sg;
            d0 -= m->cfg.v_drop_v * sg;
        } else {
            d1 = -(v_edge + m->cfg.v_drop_v) * sg;
            d0 = d1;
        }
        v[x][0] = d0;
        v[x][1] = v_dc_v + d1;
    }
}

/* dq phase currents -> abc at the angle (c, s). */
static void dq_to_abc(float i_d, float i_q, float c, float s, float i_abc[3])
{
    float al, be;
    tf_inv_park(i_d, i_q, c, s, &al, &be);
    tf_inv_clarke(al, be, &i_abc[0], &i_abc[1], &i_abc[2]);
}

/* Pole voltages of each leg for both switch positions, v[leg][s]: with the firmware's dead-time
 * model (phase currents from i_d, i_q at the angle (c, s)) or ideal (0 and v_dc). */
static void pole_voltages(const mpcc_t *m, bool dt_on, float v_dc_v, uint16_t prev, float i_d,
                          float i_q, float c, float s, float v[3][2])
{
    uint16_t x;
    if (dt_on) {
        float i_abc[3];
        dq_to_abc(i_d, i_q, c, s, i_abc);
        leg_voltages(m, v_dc_v, prev, i_abc, v);
        return;
    }
    for (x = 0u; x < 3u; x++) {
        v[x][0] = 0.0f;
        v[x][1] = v_dc_v;
    }
}

/* Rotate (c, s) forward by the angle whose cos/sin are (cd, sd). */
static void rot(float *c, float *s, float cd, float sd)
{
    const float c0 = *c;
    *c = c0 * cd - *s * sd;
    *s = *s * cd + c0 * sd;
}

/* Best candidate so far (mpcc_step's selection). */
typedef struct {
    uint16_t best, best_ch;
    float best_j, best_ed, best_eq;
} mpcc_pick_t;

/* Cost of candidate cd_ from the per-leg contributions (sab: legs a + b for the four (s_a, s_b)
 * pairs, pc: leg c), and the selection rule: lower cost wins, NaN never wins against a number, an
 * exact tie goes to fewer switch changes from prev. first: the first candidate (always taken). */
static inline void mpcc_consider(mpcc_pick_t *k, bool first, uint16_t prev, uint16_t cd_, float e_d,
                                 float e_q, float rho, const float sd_ab[4], const float sq_ab[4],
                                 const float pd_c[2], const float pq_c[2])
{
    const uint16_t ab = (uint16_t)(cd_ & 3u), sc = (uint16_t)((cd_ >> 2) & 1u);
    const float ed = e_d - (sd_ab[ab] + pd_c[sc]);
    const float eq = e_q - (sq_ab[ab] + pq_c[sc]);
    const float j = ed * ed + rho * eq * eq;
    if (first || j < k->best_j || k->best_j != k->best_j) {
        k->best = cd_;
        k->best_j = j;
        k->best_ed = ed;
        k->best_eq = eq;
        k->best_ch = n_changes(prev, cd_);
    } else if (j == k->best_j) {
        /* exact tie (V0/V7 without a switching dead-time model): fewer switch changes */
        const uint16_t ch = n_changes(prev, cd_);
        if (ch < k->best_ch) {
            k->best = cd_;
            k->best_ed = ed;
            k->best_eq = eq;
            k->best_ch = ch;
        }
    }
}

void mpcc_step(mpcc_t *m, const mpcc_in_t *in, mpcc_out_t *out)
{
    mpcc_step_cs(m, in, cosf(in->theta_e_rad), sinf(in->theta_e_rad), out);
}

void mpcc_step_cs(mpcc_t *m, const mpcc_in_t *in, float cos_th, float sin_th, mpcc_out_t *out)
{
    const float ts = m->cfg.ts_s;
    const float w = in->omega_e_rad_s;
    const float r = in->r_s_ohm;
    const bool dt_on = (m->cfg.dead_time_s > 0.0f) || (m->cfg.v_drop_v > 0.0f);
    const bool comp = (m->cfg.delay_comp == MPCC_DELAY_COMP_ON);
    float c0, s0, c1, s1, ck1, sk1, c2, s2, cd, sd, half, h2;
    float v[3][2];
    float g_d, g_q, u_al, u_be, u_d1, u_q1, i_d1, i_q1, e_d, e_q;
    float gd[3], gq[3], pd[3][2], pq[3][2], sd_ab[4], sq_ab[4];
    uint16_t x, n, best;
    mpcc_pick_t pk;
    float best_j, best_ed, best_eq, ref_d, ref_q;

    /* ---- predictor gains (reciprocals cached: no division unless the parameters change) */
    if (!(in->l_d_h > MPCC_L_MIN_H) || !(in->l_q_h > MPCC_L_MIN_H) || !(in->v_dc_v >= 0.0f)) {
        /* unusable parameters: apply a zero vector, report the applied one */
        best = (n_changes(m->sw_prev, 7u) < n_changes(m->sw_prev, 0u)) ? 7u : 0u;
        out->s_abc_applied = m->sw_prev;
        out->u_d_v = out->u_q_v = out->u_d_avg_v = out->u_q_avg_v = 0.0f;
        out->i_d_k1_a = out->i_d_k2_a = in->i_d_a;
        out->i_q_k1_a = out->i_q_k2_a = in->i_q_a;
        out->cost = 0.0f;
        m->sw_prev2 = m->sw_prev;
        m->sw_prev = best;
        out->s_abc_next = best;
        out->s_a = (uint16_t)(best & 1u);
        out->s_b = (uint16_t)((best >> 1) & 1u);
        out->s_c = (uint16_t)((best >> 2) & 1u);
        return;
    }
    if (in->l_d_h != m->l_d_cached_h) {
        m->l_d_cached_h = in->l_d_h;
        m->inv_l_d = 1.0f / in->l_d_h;
    }
    if (in->l_q_h != m->l_q_cached_h) {
        m->l_q_cached_h = in->l_q_h;
        m->inv_l_q = 1.0f / in->l_q_h;
    }
    g_d = ts * m->inv_l_d;
    g_q = ts * m->inv_l_q;

    /* ---- angles: theta (sample), theta + wTs/2 (mid of [k, k+1)), theta + wTs (k+1),
     * theta + 3wTs/2 (mid of [k+1, k+2)). One sinf/cosf pair (the caller's), the rest by small
     * rotations. */
    c0 = cos_th;
    s0 = sin_th;
    half = 0.5f * w * ts;
    if (half > 0.5f) {
        half = 0.5f;
    } else if (half < -0.5f) {
        half = -0.5f;
    }
    h2 = half * half;
    cd = 1.0f - h2 * (0.5f - h2 * (1.0f / 24.0f));
    sd = half * (1.0f - h2 * ((1.0f / 6.0f) - h2 * (1.0f / 120.0f)));
    c1 = c0;
    s1 = s0;
    rot(&c1, &s1, cd, sd);
    ck1 = c1;
    sk1 = s1;
    rot(&ck1, &sk1, cd, sd);
    c2 = ck1;
    s2 = sk1;
    rot(&c2, &s2, cd, sd);

    /* ---- the vector applied during [k, k+1): chosen last call */
    {
        const uint16_t p = m->sw_prev;
        float ua = 0.0f, ub = 0.0f;
        pole_voltages(m, dt_on, in->v_dc_v, m->sw_prev2, in->i_d_a, in->i_q_a, c0, s0, v);
        for (x = 0u; x < 3u; x++) {
            const float vx = v[x][(p >> x) & 1u];
            const uint16_t unit = (uint16_t)(1u << x);
            ua += vx * k_vec_alpha[unit];
            ub += vx * k_vec_beta[unit];
        }
        u_al = ua;
        u_be = ub;
        if (m->ext_applied) { /* the first period after a handover: the previous occupant's */
            m->ext_applied = false;
            u_al = m->ext_u_alpha_v;
            u_be = m->ext_u_beta_v;
        }
    }
    tf_park(u_al, u_be, c0, s0, &out->u_d_v, &out->u_q_v);
    tf_park(u_al, u_be, c1, s1, &u_d1, &u_q1);
    out->u_d_avg_v = u_d1;
    out->u_q_avg_v = u_q1;
    out->s_abc_applied = m->sw_prev;

    /* ---- step k -> k+1 with the applied vector (delay compensation), eq. (2) corrected */
    if (comp) {
        i_d1 = in->i_d_a + g_d * (u_d1 - r * in->i_d_a + w * in->l_q_h * in->i_q_a);
        i_q1 =
            in->i_q_a + g_q * (u_q1 - r * in->i_q_a - w * in->l_d_h * in->i_d_a - w * in->psi_f_wb);
    } else {
        /* uncompensated: pretend the new vector acts at once, i.e. predict one step from i(k) */
        i_d1 = in->i_d_a;
        i_q1 = in->i_q_a;
        c2 = c1;
        s2 = s1;
        ck1 = c0;
        sk1 = s0;
    }
    out->i_d_k1_a = i_d1;
    out->i_q_k1_a = i_q1;

    /* ---- offset compensation: integrate the sampled error, shift the references */
    if (m->cfg.k_int_rad_s > 0.0f) {
        const float kt = m->cfg.k_int_rad_s * ts;
        const float lim = m->cfg.int_max_a;
        const float ed0 = clampf(in->i_d_ref_a - in->i_d_a, lim);
        const float eq0 = clampf(in->i_q_ref_a - in->i_q_a, lim);
        if (ed0 == ed0 && eq0 == eq0) {
            m->int_d_a = clampf(m->int_d_a + kt * ed0, lim);
            m->int_q_a = clampf(m->int_q_a + kt * eq0, lim);
        }
    }
    ref_d = in->i_d_ref_a + m->int_d_a;
    ref_q = in->i_q_ref_a + m->int_q_a;

    /* ---- step k+1 -> k+2, eq. (3) corrected: i2 = base + g u2(candidate) */
    e_d = ref_d - (i_d1 + g_d * (-r * i_d1 + w * in->l_q_h * i_q1));
    e_q = ref_q - (i_q1 + g_q * (-r * i_q1 - w * in->l_d_h * i_d1 - w * in->psi_f_wb));

    /* per-leg unit pole voltage in dq at theta + 3wTs/2, scaled by Ts/L */
    for (x = 0u; x < 3u; x++) {
        const uint16_t unit = (uint16_t)(1u << x);
        float ud, uq;
        tf_park(k_vec_alpha[unit], k_vec_beta[unit], c2, s2, &ud, &uq);
        gd[x] = g_d * ud;
        gq[x] = g_q * uq;
    }
    pole_voltages(m, dt_on, in->v_dc_v, m->sw_prev, i_d1, i_q1, ck1, sk1, v);

    /* ---- candidates: the contribution of each leg for both switch positions, and the sums of
     * legs a and b for the four (s_a, s_b) pairs; a candidate then costs two additions per axis.
     * Same operations in the same order as (va gd[0] + vb gd[1]) + vc gd[2]: the same result bit
     * for bit. */
    for (x = 0u; x < 3u; x++) {
        pd[x][0] = v[x][0] * gd[x];
        pd[x][1] = v[x][1] * gd[x];
        pq[x][0] = v[x][0] * gq[x];
        pq[x][1] = v[x][1] * gq[x];
    }
    for (n = 0u; n < 4u; n++) {
        sd_ab[n] = pd[0][n & 1u] + pd[1][n >> 1];
        sq_ab[n] = pq[0][n & 1u] + pq[1][n >> 1];
    }
    pk.best = 0u;
    pk.best_ch = 4u;
    pk.best_j = 0.0f;
    pk.best_ed = 0.0f;
    pk.best_eq = 0.0f;
    if (m->cfg.cand_set == MPCC_CAND_ADJACENT) {
        for (n = 0u; n < 3u; n++) {
            mpcc_consider(&pk, n == 0u, m->sw_prev, (uint16_t)(m->sw_prev ^ (1u << n)), e_d, e_q,
                          m->cfg.rho, sd_ab, sq_ab, pd[2], pq[2]);
        }
    } else {
        /* all 8 states in the paper's order V0, V1 (100), V2 (110), V3 (010), V4 (011), V5 (001),
         * V6 (101), V7 (111), as codes (s_a is bit 0), written out so that every index is a constant */
        const uint16_t sp = m->sw_prev;
        const float rho = m->cfg.rho;
        mpcc_consider(&pk, true, sp, 0u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
        mpcc_consider(&pk, false, sp, 1u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
        mpcc_consider(&pk, false, sp, 3u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
        mpcc_consider(&pk, false, sp, 2u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
        mpcc_consider(&pk, false, sp, 6u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
        mpcc_consider(&pk, false, sp, 4u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
        mpcc_consider(&pk, false, sp, 5u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
        mpcc_consider(&pk, false, sp, 7u, e_d, e_q, rho, sd_ab, sq_ab, pd[2], pq[2]);
    }
    best = pk.best;
    best_j = pk.best_j;
    best_ed = pk.best_ed;
    best_eq = pk.best_eq;

    out->cost = best_j;
    out->i_d_k2_a = ref_d - best_ed;
    out->i_q_k2_a = ref_q - best_eq;
    m->sw_prev2 = m->sw_prev;
    m->sw_prev = best;
    out->s_abc_next = best;
    out->s_a = (uint16_t)(best & 1u);
    out->s_b = (uint16_t)((best >> 1) & 1u);
    out->s_c = (uint16_t)((best >> 2) & 1u);
}
