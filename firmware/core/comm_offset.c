/* Commissioning steps with the PWM off: current-sensor offsets (four blocks: mean and spread)
 * and the DC-link voltage (mean, ripple). docs/commissioning.md. */
#include "comm.h"

#include <math.h>

#define OFF_SETTLE_S   0.02f /* currents of the previous run have decayed */
#define OFF_BLOCK_S    0.05f
#define OFF_BLOCKS     4u
#define OFF_MAX_A      1.0f  /* a larger offset is a sensor fault, not a calibration */
#define OFF_NOISE_MAX  0.5f  /* rms noise of a sample, A */
#define OFF_SPREAD_MAX 0.02f /* block means may differ by this much, A */

void comm_offset_step(comm_t *c, comm_out_t *out)
{
    uint16_t k;
    out->pwm_on = false;
    if (c->phase == 0u) {
        if (comm_elapsed(c, OFF_SETTLE_S)) {
            comm_next_phase(c);
            c->n_blk = 0u;
        }
        return;
    }
    c->acc[0] += c->ia;
    c->acc[1] += c->ib;
    c->acc[2] += c->ic;
    c->acc[3] += c->ia * c->ia + c->ib * c->ib + c->ic * c->ic;
    c->acc_n++;
    if (!comm_elapsed(c, OFF_BLOCK_S)) {
        return;
    }
    {
        const float n = (float)c->acc_n;
        float var;
        for (k = 0u; k < 3u; k++) {
            c->blk[c->n_blk][k] = c->acc[k] / n;
        }
        var = c->acc[3] / (3.0f * n) - (c->blk[c->n_blk][0] * c->blk[c->n_blk][0] +
                                        c->blk[c->n_blk][1] * c->blk[c->n_blk][1] +
                                        c->blk[c->n_blk][2] * c->blk[c->n_blk][2]) /
                                           3.0f;
        c->blk[c->n_blk][3] = var > 0.0f ? sqrtf(var) : 0.0f;
    }
    c->n_blk = (uint16_t)(c->n_blk + 1u);
    c->t = 0u;
    comm_acc_reset(c);
    if (c->n_blk < OFF_BLOCKS) {
        return;
    }
    for (k = 0u; k < 4u; k++) {
        float m = 0.0f, lo = 1e30f, hi = -1e30f;
        uint16_t b;
        for (b = 0u; b < OFF_BLOCKS; b++) {
            m += c->blk[b][k];
            lo = c->blk[b][k] < lo ? c->blk[b][k] : lo;
            hi = c->blk[b][k] > hi ? c->blk[b][k] : hi;
        }
        c->res.value[k] = m / (float)OFF_BLOCKS;
        c->res.spread[k] = 0.5f * (hi - lo);
    }
    for (k = 0u; k < 3u; k++) {
        if (!(fabsf(c->res.value[k]) <= OFF_MAX_A)) {
            comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
            return;
        }
        if (!(c->res.spread[k] <= OFF_SPREAD_MAX)) {
            comm_fail(c, PROTO_COMMISSION_FAIL_NOT_REPEATABLE);
            return;
        }
    }
    if (!(c->res.value[3] <= OFF_NOISE_MAX)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
        return;
    }
    /* from now on the steps see offset-free samples */
    c->off_a += c->res.value[0];
    c->off_b += c->res.value[1];
    c->off_c += c->res.value[2];
    comm_finish_step(c);
}

#define VDC_WINDOW_S   0.1f
#define VDC_RIPPLE_MAX 0.1f /* peak-to-peak, relative to the mean */

void comm_vdc_step(comm_t *c, comm_out_t *out)
{
    out->pwm_on = false;
    if (c->t == 0u) {
        c->acc[1] = 1e30f;
        c->acc[2] = -1e30f;
    }
    c->acc[0] += c->v_dc;
    c->acc[1] = c->v_dc < c->acc[1] ? c->v_dc : c->acc[1];
    c->acc[2] = c->v_dc > c->acc[2] ? c->v_dc : c->acc[2];
    c->acc[3] += c->v_dc * c->v_dc;
    c->acc_n++;
    if (!comm_elapsed(c, VDC_WINDOW_S)) {
        return;
    }
    {
        const float n = (float)c->acc_n, m = c->acc[0] / n;
        const float var = c->acc[3] / n - m * m;
        c->res.value[0] = m;
        c->res.value[1] = c->acc[1];
        c->res.value[2] = c->acc[2];
        c->res.value[3] = var > 0.0f ? sqrtf(var) : 0.0f;
        c->res.spread[0] = 0.5f * (c->acc[2] - c->acc[1]);
        if (!(m >= c->cfg.v_dc_min_v && m <= c->cfg.v_dc_max_v) ||
            !(c->acc[2] - c->acc[1] <= VDC_RIPPLE_MAX * m)) {
            comm_fail(c, PROTO_COMMISSION_FAIL_V_DC);
            return;
        }
    }
    comm_finish_step(c);
}
