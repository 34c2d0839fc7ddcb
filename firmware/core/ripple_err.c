/* The saliency phase detector of the ripple PLL (ripple_err.h). */
#include "ripple_err.h"

#include <string.h>

void rerr_gamma_linear(rerr_gamma_t *m, float l_d_h, float l_q_h)
{
    memset(m, 0, sizeof(*m));
    m->a0 = l_d_h > 0.0f ? 1.0f / l_d_h : 0.0f;
    m->b0 = l_q_h > 0.0f ? 1.0f / l_q_h : 0.0f;
}

static float clampf(float x, float hi)
{
    return x < 0.0f ? 0.0f : (x > hi ? hi : x);
}

static void tab_at(const rerr_tab_t *t, float i_d_a, float i_q_a, rerr_g_t *g)
{
    const float x = clampf((i_d_a - t->id0_a) * t->inv_did, (float)(t->nd - 1u) - 1e-3f);
    const float y = clampf((i_q_a - t->iq0_a) * t->inv_diq, (float)(t->nq - 1u) - 1e-3f);
    const uint16_t j = (uint16_t)x, k = (uint16_t)y;
    const float fx = x - (float)j, fy = y - (float)k;
    const uint16_t n00 = (uint16_t)(k * t->nd + j), n01 = (uint16_t)(n00 + t->nd);
    float r[4];
    int c;
    for (c = 0; c < 4; c++) {
        const float lo = t->g[n00][c] + fx * (t->g[n00 + 1u][c] - t->g[n00][c]);
        const float hi = t->g[n01][c] + fx * (t->g[n01 + 1u][c] - t->g[n01][c]);
        r[c] = lo + fy * (hi - lo);
    }
    g->g_dd = r[0];
    g->g_qq = r[1];
    g->g_dq = r[2];
    g->g_qd = r[3];
}

void rerr_gamma_at(const rerr_gamma_t *m, float i_d_a, float i_q_a, rerr_g_t *g)
{
    const float d2 = i_d_a * i_d_a, q2 = i_q_a * i_q_a;
    if (m->tab != NULL && m->tab->nd >= 2u && m->tab->nq >= 2u) {
        tab_at(m->tab, i_d_a, i_q_a, g);
        return;
    }
    g->g_dd = m->a0 + m->a1 * i_d_a + m->a2 * d2 + m->a3 * q2;
    g->g_qq = m->b0 + m->b1 * i_d_a + m->b2 * d2 + m->b3 * q2;
    g->g_dq = i_q_a * (m->c0 + m->c1 * i_d_a);
    g->g_qd = g->g_dq;
}

void rerr_eval(const rerr_in_t *in, float ts_s, rerr_out_t *out)
{
    const float dc = 0.5f * (in->g.g_dd - in->g.g_qq), ds = 0.5f * (in->g.g_dq + in->g.g_qd);
    const float num_s = in->e_q_a * in->u_d_v + in->e_d_a * in->u_q_v;
    const float num_c = in->e_d_a * in->u_d_v - in->e_q_a * in->u_q_v;
    const float u2 = in->u_d_v * in->u_d_v + in->u_q_v * in->u_q_v;
    out->sn = num_s * dc - num_c * ds;
    out->cn = num_c * dc + num_s * ds;
    out->norm = ts_s * (dc * dc + ds * ds) * u2;
}
