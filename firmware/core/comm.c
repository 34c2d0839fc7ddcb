/* Commissioning sequencer and what its steps share (comm.h, docs/commissioning.md). */
#include "comm.h"
#include "transforms.h"

#include <math.h>
#include <string.h>

#define COMM_CC_BW_RAD_S 940.0f /* current loops: 150 Hz, well inside the one-period delay */

void comm_start(comm_t *c, const comm_cfg_t *cfg)
{
    memset(c, 0, sizeof(*c));
    c->cfg = *cfg;
    if (!(c->cfg.ts_s > 0.0f)) {
        c->cfg.ts_s = 50.0e-6f;
    }
    c->kp_d = cfg->motor.l_d_h * COMM_CC_BW_RAD_S;
    c->ki_d = cfg->motor.r_s_ohm * COMM_CC_BW_RAD_S;
    c->kp_q = cfg->motor.l_q_h * COMM_CC_BW_RAD_S;
    c->ki_q = cfg->motor.r_s_ohm * COMM_CC_BW_RAD_S;
    c->r_ohm = cfg->motor.r_s_ohm;
    c->l_d_h = cfg->motor.l_d_h;
    c->l_q_h = cfg->motor.l_q_h;
    c->inv_i_dt_a = cfg->i_dt_nom_a > 0.0f ? cfg->i_dt_nom_a : 0.5f;
    c->inv_drop_v = cfg->v_drop_nom_v;
    c->step = 0u;
    while (c->step < COMM_N_STEPS && (((uint16_t)(c->cfg.steps >> c->step)) & 1u) == 0u) {
        c->step = (uint16_t)(c->step + 1u);
    }
    c->step_started = true;
    c->status = (uint16_t)(c->step < COMM_N_STEPS ? COMM_RUNNING : COMM_DONE);
    c->c_rot = 1.0f;
}

float comm_dt(const comm_t *c, float seconds_f)
{
    return seconds_f / c->cfg.ts_s;
}

bool comm_elapsed(const comm_t *c, float seconds_f)
{
    return (float)c->t >= comm_dt(c, seconds_f);
}

void comm_acc_reset(comm_t *c)
{
    memset(c->acc, 0, sizeof(c->acc));
    c->acc_n = 0u;
}

void comm_next_phase(comm_t *c)
{
    c->phase = (uint16_t)(c->phase + 1u);
    c->t = 0u;
    comm_acc_reset(c);
}

void comm_fail(comm_t *c, uint16_t reason)
{
    c->status = COMM_FAILED;
    c->fail_reason = reason;
    c->dpwm_lo = false;
    c->res.step = c->step;
    c->res.status = reason;
    c->result_due = true;
}

void comm_finish_step(comm_t *c)
{
    c->res.step = c->step;
    c->res.status = 0u;
    c->result_due = true;
    c->dpwm_lo = false;
    c->step = (uint16_t)(c->step + 1u);
    while (c->step < COMM_N_STEPS && (((uint16_t)(c->cfg.steps >> c->step)) & 1u) == 0u) {
        c->step = (uint16_t)(c->step + 1u);
    }
    c->phase = 0u;
    c->t = 0u;
    c->int_d = 0.0f;
    c->int_q = 0.0f;
    c->n_blk = 0u;
    c->st_k = 0u;
    c->st_n = 0u;
    memset(c->blk, 0, sizeof(c->blk));
    comm_acc_reset(c);
    c->step_started = c->step < COMM_N_STEPS;
    if (c->step >= COMM_N_STEPS) {
        c->status = COMM_DONE;
    }
}

float comm_smooth_sign(float i, float i_dt)
{
    float x, x2;
    if (!(i_dt > 0.0f)) {
        return i > 0.0f ? 1.0f : (i < 0.0f ? -1.0f : 0.0f);
    }
    x = i / i_dt;
    if (x >= 3.0f) {
        return 1.0f;
    }
    if (x <= -3.0f) {
        return -1.0f;
    }
    x2 = x * x;
    return x * (27.0f + x2) / (27.0f + 9.0f * x2);
}

float comm_inv_plateau(const comm_t *c, float v_dc)
{
    const float drop = c->inv_drop_v < c->inv_v ? c->inv_drop_v : c->inv_v;
    if (!c->have_inv) {
        return 0.0f;
    }
    return c->inv_vdc_v > 1.0f ? (c->inv_v - drop) * v_dc / c->inv_vdc_v + drop : c->inv_v;
}

void comm_inv_dist(const comm_t *c, const float i_abc[3], float cs, float sn, float *d, float *q)
{
    float al, be;
    const float v = comm_inv_plateau(c, c->v_dc);
    tf_clarke(-v * comm_smooth_sign(i_abc[0], c->inv_i_dt_a),
              -v * comm_smooth_sign(i_abc[1], c->inv_i_dt_a),
              -v * comm_smooth_sign(i_abc[2], c->inv_i_dt_a), &al, &be);
    tf_park(al, be, cs, sn, d, q);
}

void comm_voltage(comm_t *c, float cs, float sn, float u_d, float u_q, comm_out_t *out)
{
    float al, be, ua, ub, uc, hi, lo, z, inv;
    uint16_t x;
    tf_inv_park(u_d, u_q, cs, sn, &al, &be);
    tf_inv_clarke(al, be, &ua, &ub, &uc);
    hi = ua > ub ? ua : ub;
    hi = uc > hi ? uc : hi;
    lo = ua < ub ? ua : ub;
    lo = uc < lo ? uc : lo;
    inv = c->v_dc > 1.0f ? 1.0f / c->v_dc : 0.0f;
    if (c->dpwm_lo) { /* discontinuous PWM: the lowest leg sits at the lower rail (duty exactly 0) */
        out->duty[0] = (ua - lo) * inv;
        out->duty[1] = (ub - lo) * inv;
        out->duty[2] = (uc - lo) * inv;
    } else {
        z = -0.5f * (hi + lo); /* min-max zero sequence: the space-vector range */
        out->duty[0] = 0.5f + (ua + z) * inv;
        out->duty[1] = 0.5f + (ub + z) * inv;
        out->duty[2] = 0.5f + (uc + z) * inv;
    }
    for (x = 0u; x < 3u; x++) {
        out->duty[x] = out->duty[x] < 0.0f ? 0.0f : (out->duty[x] > 1.0f ? 1.0f : out->duty[x]);
    }
    out->pwm_on = true;
    c->u_d = u_d;
    c->u_q = u_q;
    out->u_d_v = u_d;
    out->u_q_v = u_q;
}

static float clampf(float x, float lim)
{
    return x > lim ? lim : (x < -lim ? -lim : x);
}

void comm_current(comm_t *c, float cs, float sn, float i_d_ref, float i_q_ref, float *i_d,
                  float *i_q, comm_out_t *out)
{
    float al, be, ed, eq, ud, uq;
    const float u_lim = 0.55f * c->v_dc;
    tf_clarke(c->ia, c->ib, c->ic, &al, &be);
    tf_park(al, be, cs, sn, i_d, i_q);
    ed = i_d_ref - *i_d;
    eq = i_q_ref - *i_q;
    c->int_d = clampf(c->int_d + c->ki_d * c->cfg.ts_s * ed, u_lim);
    c->int_q = clampf(c->int_q + c->ki_q * c->cfg.ts_s * eq, u_lim);
    ud = clampf(c->kp_d * ed + c->int_d, u_lim);
    uq = clampf(c->kp_q * eq + c->int_q, u_lim);
    if (c->adv_rad != 0.0f) {
        const float ca = cosf(c->adv_rad), sa = sinf(c->adv_rad);
        const float c2 = cs * ca - sn * sa;
        sn = sn * ca + cs * sa;
        cs = c2;
    }
    comm_voltage(c, cs, sn, ud, uq, out);
    out->i_d_a = *i_d;
    out->i_q_a = *i_q;
    out->i_d_ref_a = i_d_ref;
    out->i_q_ref_a = i_q_ref;
}

bool comm_over_current(comm_t *c)
{
    const float lim = c->i_max_step;
    if (!(fabsf(c->ia) <= lim) || !(fabsf(c->ib) <= lim) || !(fabsf(c->ic) <= lim)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_OVER_CURRENT);
        return true;
    }
    return false;
}

/* ------------------------------------------------------------------ regression */

void comm_reg_reset(comm_reg_t *r)
{
    memset(r, 0, sizeof(*r));
}

void comm_reg_add(comm_reg_t *r, const float x[COMM_REG_N], float y)
{
    uint16_t i, j;
    for (i = 0u; i < COMM_REG_N; i++) {
        for (j = 0u; j < COMM_REG_N; j++) {
            r->sxx[i][j] += x[i] * x[j];
        }
        r->sxy[i] += x[i] * y;
    }
    r->n++;
}

/* Normal equations by Gaussian elimination with partial pivoting. */
bool comm_reg_solve(const comm_reg_t *r, uint16_t n, float a[COMM_REG_N])
{
    float m[COMM_REG_N][COMM_REG_N + 1u];
    uint16_t i, j, k, p;
    if (n > COMM_REG_N) {
        n = COMM_REG_N;
    }
    for (i = 0u; i < n; i++) {
        for (j = 0u; j < n; j++) {
            m[i][j] = r->sxx[i][j];
        }
        m[i][n] = r->sxy[i];
    }
    for (k = 0u; k < n; k++) {
        p = k;
        for (i = (uint16_t)(k + 1u); i < n; i++) {
            if (fabsf(m[i][k]) > fabsf(m[p][k])) {
                p = i;
            }
        }
        if (!(fabsf(m[p][k]) > 1e-20f)) {
            return false;
        }
        for (j = 0u; j <= n; j++) {
            float t = m[k][j];
            m[k][j] = m[p][j];
            m[p][j] = t;
        }
        for (i = (uint16_t)(k + 1u); i < n; i++) {
            float f = m[i][k] / m[k][k];
            for (j = k; j <= n; j++) {
                m[i][j] -= f * m[k][j];
            }
        }
    }
    for (i = n; i-- > 0u;) {
        float s = m[i][n];
        for (j = (uint16_t)(i + 1u); j < n; j++) {
            s -= m[i][j] * a[j];
        }
        a[i] = s / m[i][i];
    }
    return true;
}

/* ------------------------------------------------------------------ the sequence */

static void sample(comm_t *c, const comm_in_t *in)
{
    c->ia = (in->i_a_a - c->off_a) / (1.0f + c->gerr_a);
    c->ib = (in->i_b_a - c->off_b) / (1.0f + c->gerr_b);
    c->ic = (in->i_c_a - c->off_c) / (1.0f + c->gerr_c);
    c->v_dc = in->v_dc_v;
    c->th_rotor = tf_wrap_2pi(in->theta_enc_rad + c->enc_delta_rad);
    c->c_rot = cosf(c->th_rotor);
    c->s_rot = sinf(c->th_rotor);
}

uint16_t comm_step(comm_t *c, const comm_in_t *in, comm_out_t *out)
{
    const uint16_t step = c->step;
    memset(out, 0, sizeof(*out));
    if (c->status != COMM_RUNNING) {
        return c->status;
    }
    sample(c, in);
    switch (c->step) {
    case PROTO_COMMISSION_STEP_OFFSETS:
        comm_offset_step(c, out);
        break;
    case PROTO_COMMISSION_STEP_V_DC:
        comm_vdc_step(c, out);
        break;
    case PROTO_COMMISSION_STEP_ENCODER:
        comm_align_step(c, in, out);
        break;
    case PROTO_COMMISSION_STEP_INVERTER:
        comm_inverter_step(c, out);
        break;
    case PROTO_COMMISSION_STEP_R_S:
        comm_r_step(c, out);
        break;
    case PROTO_COMMISSION_STEP_L_DQ:
        comm_l_step(c, out);
        break;
    default:
        comm_spin_step(c, in, out);
        break;
    }
    if (c->step == step) { /* a new step starts at t = 0 */
        c->t++;
    }
    c->t_total++;
    if (c->status == COMM_FAILED) {
        memset(out, 0, sizeof(*out)); /* PWM off at once */
    }
    return c->status;
}

bool comm_brake(comm_t *c, const comm_in_t *in, comm_out_t *out)
{
    float id, iq, iq_ref;
    memset(out, 0, sizeof(*out));
    if (!c->have_enc || fabsf(in->omega_e_rad_s) < 0.3f * (float)c->cfg.motor.pole_pairs) {
        return true; /* standstill (3 r/min), or no angle to brake with: PWM off */
    }
    sample(c, in);
    c->i_max_step = 1.5f * c->cfg.motor.i_max_a;
    iq_ref = clampf(-0.02f * in->omega_e_rad_s, 0.5f * c->cfg.motor.i_max_a);
    comm_current(c, c->c_rot, c->s_rot, 0.0f, iq_ref, &id, &iq, out);
    return false;
}
