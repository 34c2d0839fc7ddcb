#include "r_inject.h"

#include <math.h>

void rinj_gap(rinj_t *r)
{
    r->w_count = 0u;
    r->w_id = r->w_iq = r->w_ud = r->w_uq = r->w_c = r->w_s = 0.0f;
    r->w_id0 = r->w_iq0 = 0.0f;
}

void rinj_reset(rinj_t *r)
{
    r->s_ii = r->s_id = r->s_dd = r->s_ui = r->s_ud = 0.0f;
    r->n = 0u;
    rinj_gap(r);
}

void rinj_init(rinj_t *r, const rinj_cfg_t *cfg)
{
    r->cfg = *cfg;
    if (!(r->cfg.sep_min > 0.0f && r->cfg.sep_min < 1.0f)) {
        r->cfg.sep_min = 1e-3f;
    }
    if (r->cfg.n_window < 1u) {
        r->cfg.n_window = 20u;
    }
    if (!(r->cfg.ts_s > 0.0f)) {
        r->cfg.ts_s = 50e-6f;
    }
    if (!(r->cfg.l_d_h >= 0.0f)) {
        r->cfg.l_d_h = 0.0f;
    }
    if (!(r->cfg.l_q_h >= 0.0f)) {
        r->cfg.l_q_h = 0.0f;
    }
    rinj_reset(r);
}

static float sgnf(float x)
{
    return x >= 0.0f ? 1.0f : -1.0f; /* (31) */
}

/* Close the running window at the sample (i_d_end, i_q_end) that follows its last period. */
static void close_window(rinj_t *r, float i_d_end, float i_q_end)
{
    const float k = 1.0f / (float)r->w_count;
    const float t = (float)r->w_count * r->cfg.ts_s;
    /* trapezoid: sum_{j=0}^{n-1} i_j + (i_n - i_0) / 2; voltage minus the residual L di/dt */
    const float i_d = (r->w_id + 0.5f * (i_d_end - r->w_id0)) * k;
    const float i_q = (r->w_iq + 0.5f * (i_q_end - r->w_iq0)) * k;
    const float u_d = r->w_ud * k - r->cfg.l_d_h * (i_d_end - r->w_id0) / t;
    const float u_q = r->w_uq * k - r->cfg.l_q_h * (i_q_end - r->w_iq0) / t;
    const float nrm = sqrtf(r->w_c * r->w_c + r->w_s * r->w_s);
    const float c = nrm > 0.0f ? r->w_c / nrm : 1.0f, s = nrm > 0.0f ? r->w_s / nrm : 0.0f;
    /* mean phase currents: inverse Park, inverse Clarke */
    const float i_al = c * i_d - s * i_q, i_be = s * i_d + c * i_q;
    const float i_a = i_al, i_b = -0.5f * i_al + 0.866025404f * i_be, i_c = -i_a - i_b;
    /* D = Park(Clarke(sgn)) */
    const float sa = sgnf(i_a), sb = sgnf(i_b), sc = sgnf(i_c);
    const float d_al = (2.0f * sa - sb - sc) * 0.333333333f;
    const float d_be = (sb - sc) * 0.577350269f;
    const float d_d = c * d_al + s * d_be;
    const float d_q = -s * d_al + c * d_be;
    r->s_ii += i_d * i_d + i_q * i_q;
    r->s_id += i_d * d_d + i_q * d_q;
    r->s_dd += d_d * d_d + d_q * d_q;
    r->s_ui += u_d * i_d + u_q * i_q;
    r->s_ud += u_d * d_d + u_q * d_q;
    r->n++;
}

void rinj_step(rinj_t *r, const rinj_in_t *in, rinj_out_t *out)
{
    if (r->w_count >= r->cfg.n_window) {
        close_window(r, in->i_d_a, in->i_q_a);
        rinj_gap(r);
    }
    if (r->w_count == 0u) {
        r->w_id0 = in->i_d_a;
        r->w_iq0 = in->i_q_a;
    }
    r->w_id += in->i_d_a;
    r->w_iq += in->i_q_a;
    r->w_ud += in->u_d_v;
    r->w_uq += in->u_q_v;
    r->w_c += cosf(in->theta_e_rad);
    r->w_s += sinf(in->theta_e_rad);
    r->w_count++;
    rinj_result(r, out);
}

void rinj_result(const rinj_t *r, rinj_out_t *out)
{
    const float prod = r->s_ii * r->s_dd;
    const float det = prod - r->s_id * r->s_id;
    out->n = r->n;
    out->separable = false;
    out->v_dead_v = 0.0f;
    out->r_s_ohm = 0.0f;
    if (!(r->s_ii > 0.0f)) {
        return;
    }
    if (prod > 0.0f && det > r->cfg.sep_min * prod) {
        /* [S_ii -S_iD; -S_iD S_DD] [R; V] = [S_ui; -S_uD] */
        out->r_s_ohm = (r->s_ui * r->s_dd - r->s_id * r->s_ud) / det;
        out->v_dead_v = (r->s_id * r->s_ui - r->s_ii * r->s_ud) / det;
        out->separable = true;
    } else {
        out->r_s_ohm = r->s_ui / r->s_ii;
    }
}
