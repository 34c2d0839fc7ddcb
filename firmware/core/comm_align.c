/* Commissioning step: encoder offset by d-axis alignment, with the direction, pole-pair and
 * current-sensor gain checks (docs/commissioning.md).
 *
 * A current vector of i_test along a commanded angle pulls the rotor's d axis onto it. The
 * vector steps through one electrical turn forward and back in COMM_AL_POINTS steps; at each
 * hold the offset sample is (commanded angle - encoder angle). Coulomb friction makes the
 * rotor lag by the same angle either way, so forward and backward samples average it out;
 * the points are spaced so that cogging torque does not add up. A virtual damper (the vector
 * leads against the encoder's speed) settles the rotor's swing within each hold. The sum of the
 * three phase currents with the vector along each phase gives the sensors' gain mismatch. */
#include "comm.h"
#include "transforms.h"

#include <math.h>

#define AL_POINTS     12u
#define AL_RAMP_S     0.1f
#define AL_SETTLE_S   0.3f
#define AL_MOVE_S     0.05f
#define AL_HOLD_S     0.1f
#define AL_MEAS_S     0.05f
#define AL_ZETA       0.7f
#define AL_STD_MAX    0.05f /* rad: samples that scatter more are not an alignment */
#define AL_GAIN_MAX   0.05f /* relative gain mismatch between the sensors */
#define AL_MIN_I_FRAC 0.3f

/* acc use: 0 theta_unwrap at the first hold, 1 sum e, 2 sum e^2, 3 sum forward e, 4 sum backward
 * e, 5 reference e (point 0), 6 n forward, 7 n backward; blk[0..2]: phase-current sum and the
 * magnitude with the vector along a, b, c. */

static float point_angle(uint16_t j)
{
    const uint16_t idx = j <= AL_POINTS ? j : (uint16_t)(2u * AL_POINTS - j);
    return (float)idx * (FW_TWO_PI_F / (float)AL_POINTS);
}

static void track(comm_t *c, const comm_in_t *in)
{
    c->theta_unwrap += tf_wrap_pi(in->theta_enc_rad - c->theta_last);
    c->theta_last = in->theta_enc_rad;
}

static float half_count(const comm_t *c)
{
    return c->cfg.enc_counts > 0u
               ? FW_PI_F * (float)c->cfg.motor.pole_pairs / (float)c->cfg.enc_counts
               : 0.0f;
}

static void finish(comm_t *c)
{
    const float n = c->acc[6] + c->acc[7];
    const float mean = c->acc[1] / n, var = c->acc[2] / n - mean * mean;
    const float fwd = c->acc[3] / c->acc[6], bwd = c->acc[4] / c->acc[7];
    const float turns = c->blk[3][0] / FW_TWO_PI_F;
    float e[3], emax = 0.0f;
    uint16_t x;
    /* sum of the three measured currents with the vector along phase x: 1.5 I (g_x - mean g) */
    for (x = 0u; x < 3u; x++) {
        e[x] = c->blk[x][1] > 0.0f ? c->blk[x][0] / (1.5f * c->blk[x][1]) : 0.0f;
        emax = fabsf(e[x]) > emax ? fabsf(e[x]) : emax;
    }
    /* the count is the floor of the angle: at rest it reads half a count behind on average; the
     * offset is the encoder's own (ident.c adds the half count where it matters) */
    c->res.value[0] = tf_wrap_pi(c->acc[5] + mean - half_count(c));
    c->res.value[1] = 0.5f * (fwd - bwd);
    c->res.value[2] = turns;
    c->res.value[3] = emax;
    c->res.spread[0] = var > 0.0f ? sqrtf(var) : 0.0f;
    c->res.ref[0] = e[0];
    c->res.ref[1] = e[1];
    if (!(c->res.spread[0] <= AL_STD_MAX)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_NOT_REPEATABLE);
        return;
    }
    if (!(emax <= AL_GAIN_MAX)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
        return;
    }
    c->enc_delta_rad = c->res.value[0];
    c->have_enc = true;
    c->gerr_a = (1.0f + c->gerr_a) * (1.0f + e[0]) - 1.0f;
    c->gerr_b = (1.0f + c->gerr_b) * (1.0f + e[1]) - 1.0f;
    c->gerr_c = (1.0f + c->gerr_c) * (1.0f + e[2]) - 1.0f;
    comm_finish_step(c);
}

/* At the end of the forward turn's last hold (the rotor settled on the field, as at the first
 * point's: checked as the move ended, the rotor still lagged and one turn read 0.97): the encoder
 * must have turned by one electrical turn. */
static bool check_turn(comm_t *c)
{
    const float turns = (c->theta_unwrap - c->acc[0]) / FW_TWO_PI_F;
    c->blk[3][0] = c->theta_unwrap - c->acc[0];
    c->res.value[2] = turns;
    if (turns < -0.5f) {
        comm_fail(c, PROTO_COMMISSION_FAIL_WRONG_DIRECTION);
    } else if (fabsf(turns) < 0.25f) {
        comm_fail(c, PROTO_COMMISSION_FAIL_ROTOR_STUCK);
    } else if (fabsf(turns - 1.0f) > 0.25f) {
        comm_fail(c, PROTO_COMMISSION_FAIL_POLE_PAIRS);
    }
    return c->status == COMM_RUNNING;
}

static void measure(comm_t *c, const comm_in_t *in, uint16_t j, float target)
{
    const float e = tf_wrap_pi(target - in->theta_enc_rad);
    float d;
    if (c->acc_n == 0u) {
        c->acc[5] = e; /* the reference that later samples are unwrapped against */
    }
    d = tf_wrap_pi(e - c->acc[5]);
    c->acc[1] += d;
    c->acc[2] += d * d;
    if (j <= AL_POINTS) {
        c->acc[3] += d;
        c->acc[6] += 1.0f;
    } else {
        c->acc[4] += d;
        c->acc[7] += 1.0f;
    }
    c->acc_n++;
    if (j < AL_POINTS && (j % 4u) == 0u) { /* the vector along phase a, b, c */
        const uint16_t x = (uint16_t)(j / 4u);
        const float w = 1.0f / comm_dt(c, AL_MEAS_S);
        c->blk[x][0] += (c->ia + c->ib + c->ic) * w;
        c->blk[x][1] +=
            sqrtf(c->ia * c->ia + (c->ia + 2.0f * c->ib) * (c->ia + 2.0f * c->ib) * (1.0f / 3.0f)) *
            w;
    }
}

void comm_align_step(comm_t *c, const comm_in_t *in, comm_out_t *out)
{
    const fw_motor_t *m = &c->cfg.motor;
    const float i_al = c->cfg.i_test_a;
    const float wn =
        sqrtf(1.5f * (float)m->pole_pairs * (float)m->pole_pairs * m->psi_f_wb * i_al / m->j_kgm2);
    const float kd = wn > 0.0f ? 2.0f * AL_ZETA / wn : 0.0f;
    float id, iq, target, th_v, ref = i_al;
    const uint16_t j = c->n_blk; /* point index, 0 .. 2 AL_POINTS */

    c->i_max_step = 1.5f * i_al + 1.0f;
    if (c->t_total > 0u && comm_over_current(c)) {
        return;
    }
    if (c->phase == 0u && c->t == 0u) {
        uint16_t x;
        c->theta_last = in->theta_enc_rad;
        c->theta_unwrap = 0.0f;
        c->n_blk = 0u;
        for (x = 0u; x < 4u; x++) {
            c->blk[x][0] = 0.0f;
            c->blk[x][1] = 0.0f;
        }
    }
    track(c, in);
    target = point_angle(j);
    if (c->phase == 0u) { /* ramp the current up along the first angle */
        ref = i_al * (float)c->t / comm_dt(c, AL_RAMP_S);
        if (comm_elapsed(c, AL_RAMP_S)) {
            float al = c->ia, be = (c->ia + 2.0f * c->ib) * TF_INV_SQRT3_F;
            if (!(sqrtf(al * al + be * be) >= AL_MIN_I_FRAC * i_al)) {
                comm_fail(c, PROTO_COMMISSION_FAIL_NO_CURRENT);
                return;
            }
            c->phase = 1u;
            c->t = 0u;
        }
    } else if (c->phase == 1u) { /* settle on the first angle */
        if (comm_elapsed(c, AL_SETTLE_S)) {
            c->phase = 2u;
            c->t = 0u;
        }
    } else { /* phase 2: hold at point j (measure at the end), then move to j + 1 */
        const float hold = comm_dt(c, AL_HOLD_S), meas = comm_dt(c, AL_MEAS_S);
        if ((float)c->t >= hold - meas && (float)c->t < hold) {
            if (j != 1u) { /* point 1 was reached without the damper: it may still swing */
                measure(c, in, j, target);
            }
            if (j == 0u) {
                c->acc[0] = c->theta_unwrap;
            }
        } else if ((float)c->t >= hold) {
            const float u = ((float)c->t - hold) / comm_dt(c, AL_MOVE_S);
            /* after the first step: the rotor must have followed the field forward (swapped
             * phases turn it backward, and the damper would then push instead of brake) */
            if (j == AL_POINTS && (float)c->t < hold + 1.0f && !check_turn(c)) {
                return;
            }
            if (j == 1u && (float)c->t < hold + 1.0f &&
                c->theta_unwrap - c->acc[0] < -0.25f * (FW_TWO_PI_F / (float)AL_POINTS)) {
                c->blk[3][0] = c->theta_unwrap - c->acc[0];
                c->res.value[2] = c->blk[3][0] / FW_TWO_PI_F;
                comm_fail(c, PROTO_COMMISSION_FAIL_WRONG_DIRECTION);
                return;
            }
            const float next = point_angle((uint16_t)(j + 1u));
            const float step = tf_wrap_pi(next - target);
            if (j >= 2u * AL_POINTS) {
                finish(c);
                return;
            }
            if (u >= 1.0f) {
                c->n_blk = (uint16_t)(c->n_blk + 1u);
                c->t = 0u;
                target = next;
            } else {
                target += step * 0.5f * (1.0f - cosf(FW_PI_F * u));
            }
        }
    }
    /* the damper only once the rotor is known to follow the field forward */
    th_v = target - (c->n_blk >= 2u ? kd * in->omega_e_rad_s : 0.0f);
    comm_current(c, cosf(th_v), sinf(th_v), ref, 0.0f, &id, &iq, out);
}
