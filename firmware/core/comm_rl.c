/* Commissioning steps at standstill with the rotor frame known (docs/commissioning.md):
 *   R by d-axis current injection at two levels of the same sign, both beyond the inverter's
 *   knee, so that the distortion (corrected with the measured model) drops out of the
 *   difference; both directions, repeated;
 *   L_d and L_q by voltage pulses: on a d-current bias (which keeps every phase current away
 *   from zero, so the inverter's distortion stays constant, and holds the rotor), a square-wave
 *   voltage on one axis; L = Ts / (sum of the regression coefficients of the current's change on
 *   the last three commanded voltages), which absorbs the PWM delay and the sample delay. */
#include "comm.h"
#include "transforms.h"

#include <math.h>

#define R_SETTLE_S 0.1f
#define R_MEAS_S   0.1f
#define R_LEVELS   6u

#define L_SETTLE_S 0.1f
#define L_TEST_S   0.2f
#define L_HALF_N   8u    /* periods per half-wave of the square wave */
#define L_RIPPLE   0.15f /* ripple peak-to-peak as a fraction of the test current */
#define L_SPREAD   0.05f

static float r_level(const comm_t *c, uint16_t k)
{
    float i1 = 6.0f * c->inv_i_dt_a;
    const float i2 = c->cfg.i_test_a;
    i1 = i1 > 0.4f * i2 ? i1 : 0.4f * i2;
    if (i1 > 0.7f * i2) {
        i1 = 0.7f * i2;
    }
    return ((k / 2u) % 2u == 0u ? 1.0f : -1.0f) * ((k % 2u) == 0u ? i1 : i2);
}

static void r_finish(comm_t *c)
{
    float lo = 1e30f, hi = -1e30f, sum = 0.0f, r;
    uint16_t p;
    for (p = 0u; p < R_LEVELS / 2u; p++) {
        const float di = c->blk[2u * p + 1u][0] - c->blk[2u * p][0];
        const float du = c->blk[2u * p + 1u][1] - c->blk[2u * p][1];
        r = fabsf(di) > 1e-3f ? du / di : 0.0f;
        c->res.value[1u + p] = r;
        sum += r;
        lo = r < lo ? r : lo;
        hi = r > hi ? r : hi;
    }
    r = sum / (float)(R_LEVELS / 2u);
    c->res.value[0] = r;
    c->res.spread[0] = 0.5f * (hi - lo);
    c->res.ref[0] = fabsf(r_level(c, 0u));
    c->res.ref[1] = fabsf(r_level(c, 1u));
    if (!(r >= 0.3f * c->cfg.motor.r_s_ohm && r <= 3.0f * c->cfg.motor.r_s_ohm)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
        return;
    }
    if (!(hi - lo <= 0.06f * r)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_NOT_REPEATABLE);
        return;
    }
    c->r_ohm = r;
    c->have_r = true;
    comm_finish_step(c);
}

void comm_r_step(comm_t *c, comm_out_t *out)
{
    const uint16_t k = c->n_blk;
    float id, iq, dd, dq, i3[3];
    c->i_max_step = 1.5f * c->cfg.i_test_a + 1.0f;
    if (comm_over_current(c)) {
        return;
    }
    comm_current(c, c->c_rot, c->s_rot, r_level(c, k), 0.0f, &id, &iq, out);
    if (c->phase == 0u) {
        if (comm_elapsed(c, R_SETTLE_S)) {
            comm_next_phase(c);
        }
        return;
    }
    i3[0] = c->ia;
    i3[1] = c->ib;
    i3[2] = c->ic;
    comm_inv_dist(c, i3, c->c_rot, c->s_rot, &dd, &dq);
    c->acc[0] += id;
    c->acc[1] += c->u_d + dd; /* the voltage the inverter applied */
    c->acc_n++;
    if (!comm_elapsed(c, R_MEAS_S)) {
        return;
    }
    c->blk[k][0] = c->acc[0] / (float)c->acc_n;
    c->blk[k][1] = c->acc[1] / (float)c->acc_n;
    c->n_blk = (uint16_t)(c->n_blk + 1u);
    c->phase = 0u;
    c->t = 0u;
    comm_acc_reset(c);
    if (c->n_blk >= R_LEVELS) {
        r_finish(c);
    }
}

/* ------------------------------------------------------------------ L_d, L_q */

static float l_bias(const comm_t *c)
{
    const float ripple = L_RIPPLE * c->cfg.i_test_a;
    const float b = 2.0f * (3.0f * c->inv_i_dt_a + ripple);
    return b > 0.5f * c->cfg.i_test_a ? b : 0.5f * c->cfg.i_test_a;
}

static float l_of(const comm_reg_t *a, const comm_reg_t *b, float ts_s)
{
    comm_reg_t s = *a;
    float x[COMM_REG_N];
    uint16_t i, j;
    if (b != 0) {
        for (i = 0u; i < COMM_REG_N; i++) {
            for (j = 0u; j < COMM_REG_N; j++) {
                s.sxx[i][j] += b->sxx[i][j];
            }
            s.sxy[i] += b->sxy[i];
        }
        s.n += b->n;
    }
    if (!comm_reg_solve(&s, COMM_REG_N, x)) {
        return 0.0f;
    }
    return (x[0] + x[1] + x[2]) > 0.0f ? ts_s / (x[0] + x[1] + x[2]) : 0.0f;
}

/* one test phase on axis ax (0 d, 1 q): slow integral current loops (a tenth of the step's
 * bandwidth) hold the operating point, so the rotor cannot be pushed away by the inverter's
 * distortion turning with it; the square wave (started half a half-wave in, so the current's
 * triangle is centred) rides on top. The regression sees the total commanded voltage. */
static void l_test(comm_t *c, uint16_t ax, float amp, float id, float iq, float bias,
                   comm_out_t *out)
{
    const float sq = (((c->t + L_HALF_N / 2u) / L_HALF_N) % 2u) == 0u ? 1.0f : -1.0f;
    const float i_now = ax == 0u ? id : iq;
    float u;
    const uint16_t half = (uint16_t)((float)c->t < comm_dt(c, 0.5f * L_TEST_S) ? 0u : 1u);
    /* the other axis keeps its full loop, the tested one a slow PI (a fifth of the bandwidth) */
    c->int_d += (ax == 0u ? 0.04f : 1.0f) * c->ki_d * c->cfg.ts_s * (bias - id);
    c->int_q += (ax == 1u ? 0.04f : 1.0f) * c->ki_q * c->cfg.ts_s * (0.0f - iq);
    {
        const float ud = c->int_d + (ax == 0u ? 0.2f : 1.0f) * c->kp_d * (bias - id);
        const float uq = c->int_q + (ax == 1u ? 0.2f : 1.0f) * c->kp_q * (0.0f - iq);
        u = (ax == 0u ? ud : uq) + sq * amp;
        c->u_d = ud;
        c->u_q = uq;
    }
    if (c->t >= 4u) {
        const float i_mid = 0.5f * (i_now + c->i_prev);
        float x[COMM_REG_N];
        x[0] = c->u_hist[0] - c->r_ohm * i_mid;
        x[1] = c->u_hist[1] - c->r_ohm * i_mid;
        x[2] = c->u_hist[2] - c->r_ohm * i_mid;
        x[3] = 1.0f;
        comm_reg_add(&c->reg[half], x, i_now - c->i_prev);
    }
    c->i_prev = i_now;
    c->u_hist[2] = c->u_hist[1];
    c->u_hist[1] = c->u_hist[0];
    c->u_hist[0] = u;
    if (ax == 0u) {
        comm_voltage(c, c->c_rot, c->s_rot, u, c->u_q, out);
    } else {
        comm_voltage(c, c->c_rot, c->s_rot, c->u_d, u, out);
    }
}

static bool l_result(comm_t *c, uint16_t ax, float l_nom)
{
    const float l = l_of(&c->reg[0], &c->reg[1], c->cfg.ts_s);
    const float l0 = l_of(&c->reg[0], 0, c->cfg.ts_s), l1 = l_of(&c->reg[1], 0, c->cfg.ts_s);
    c->res.value[ax] = l;
    c->res.spread[ax] = 0.5f * fabsf(l0 - l1);
    if (!(l >= 0.2f * l_nom && l <= 5.0f * l_nom)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
        return false;
    }
    if (!(fabsf(l0 - l1) <= 2.0f * L_SPREAD * l)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_NOT_REPEATABLE);
        return false;
    }
    return true;
}

void comm_l_step(comm_t *c, comm_out_t *out)
{
    const float bias = l_bias(c);
    const float n_half = (float)L_HALF_N * c->cfg.ts_s;
    const float amp_d = 0.5f * L_RIPPLE * c->cfg.i_test_a * c->cfg.motor.l_d_h / n_half * 2.0f;
    const float amp_q = 0.5f * L_RIPPLE * c->cfg.i_test_a * c->cfg.motor.l_q_h / n_half * 2.0f;
    float id, iq, al, be;
    c->i_max_step = 1.5f * c->cfg.i_test_a + 1.0f;
    if (comm_over_current(c)) {
        return;
    }
    tf_clarke(c->ia, c->ib, c->ic, &al, &be);
    tf_park(al, be, c->c_rot, c->s_rot, &id, &iq);
    switch (c->phase) {
    case 0u: /* d-current bias under current control; then its voltages are held */
    case 2u:
        comm_current(c, c->c_rot, c->s_rot, bias, 0.0f, &id, &iq, out);
        if (comm_elapsed(c, L_SETTLE_S)) {
            comm_reg_reset(&c->reg[0]);
            comm_reg_reset(&c->reg[1]);
            c->i_prev = c->phase == 0u ? id : iq;
            c->u_hist[0] = c->u_hist[1] = c->u_hist[2] = c->phase == 0u ? c->int_d : c->int_q;
            comm_next_phase(c);
        }
        break;
    case 1u:
        l_test(c, 0u, amp_d, id, iq, bias, out);
        if (comm_elapsed(c, L_TEST_S)) {
            if (!l_result(c, 0u, c->cfg.motor.l_d_h)) {
                return;
            }
            comm_next_phase(c);
        }
        break;
    default:
        l_test(c, 1u, amp_q, id, iq, bias, out);
        if (comm_elapsed(c, L_TEST_S)) {
            if (!l_result(c, 1u, c->cfg.motor.l_q_h)) {
                return;
            }
            c->res.value[2] = bias;
            c->res.value[3] = amp_d;
            c->res.ref[0] = bias;
            c->res.ref[1] = 0.0f;
            c->l_d_h = c->res.value[0];
            c->l_q_h = c->res.value[1];
            comm_finish_step(c);
        }
        break;
    }
    out->i_d_a = id;
    out->i_q_a = iq;
    out->i_d_ref_a = bias;
}
